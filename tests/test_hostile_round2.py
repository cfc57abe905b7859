"""Issue 33's findings, tried again through the CLI as a user meets them (round two).

Each case runs ``python -m terratheme.app.cli`` in a subprocess and checks what a user
sees: exit status 2 and one error line (no traceback; the progress lines a command
prints where stderr is not a terminal may come before it), no input or unnamed file
changed, no half-written output, no temporary left. Cases that need root (a tmpfs
that fills up) skip without it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import resource
import signal
import socket
import struct
import subprocess
import sys
import textwrap
import threading
import time
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest
from terratheme.core.errors import CorruptFileError
from terratheme.core.io.codec import encode_image
from terratheme.core.io.images import read_image, write_image
from terratheme.core.io.legend import parse_legend
from test_jpegxl_header import bare_codestream

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "sample_maps" / "dubai_marina.jpg"
#: a progress line of a finished stage ('render: 2.4 s'), printed where stderr is no terminal
STAGE_LINE = re.compile(r"^[\w ()-]+: \d+(\.\d+)? s$")


def run(*args, env: dict | None = None, timeout: float = 240.0, prefix: str = "",
        cwd: Path = REPO) -> subprocess.CompletedProcess:
    """The CLI with ``args`` (``prefix``: Python run before it, e.g. a fault injector)."""
    code = prefix + "\nfrom terratheme.app.cli import console_main\nconsole_main()\n"
    proc = subprocess.run([sys.executable, "-c", code, *map(str, args)], cwd=cwd,
                          capture_output=True, timeout=timeout,
                          env=dict(os.environ, PYTHONPATH=str(REPO), **(env or {})))
    return subprocess.CompletedProcess(proc.args, proc.returncode,
                                       proc.stdout.decode(errors="replace"),
                                       proc.stderr.decode(errors="replace"))


def refused(proc: subprocess.CompletedProcess, *needles: str) -> str:
    """Exit 2 and one error line holding every needle (after stage lines or a bar's \\r)."""
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-3000:])
    assert "Traceback" not in proc.stderr and proc.stderr.endswith("\n"), proc.stderr[-3000:]
    lines = [ln.rsplit("\r", 1)[-1] for ln in proc.stderr.splitlines()]
    errors = [ln for ln in lines if not STAGE_LINE.match(ln)]
    assert len(errors) == 1 and errors[0].startswith("terratheme"), proc.stderr[-3000:]
    assert " error: " in errors[0], errors[0]
    for needle in needles:
        assert needle in errors[0], errors[0]
    return errors[0]


def digest(folder: Path) -> dict[str, str]:
    """Every entry of ``folder`` (names, link targets, file bytes' SHA-256)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        rel = str(p.relative_to(folder))
        if p.is_symlink():
            out[rel] = "-> " + os.readlink(p)
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[rel] = "dir"
    return out


def temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob(".*.tt-*"))


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> Path:
    """A folder with photo.png (96 x 96 of the sample), its converted project p.ttproj
    (p.ttpack, p_colour.avif, p_preview.png) and a 3-class label image labels.png."""
    if not SAMPLE.exists():
        pytest.skip("sample_maps/dubai_marina.jpg is missing")
    folder = tmp_path_factory.mktemp("made")
    write_image(folder / "photo.png", read_image(SAMPLE)[:96, :96, :3])
    proc = run("convert", folder / "photo.png", folder / "p.ttproj")
    assert proc.returncode == 0, proc.stderr[-2000:]
    labels = np.zeros((40, 40), np.uint8)
    labels[:, 20:], labels[30:] = 1, 2
    write_image(folder / "labels.png", labels)
    return folder


# -- planted journals and temporaries ------------------------------------------------

def test_planted_journals_and_temporaries_are_left_alone(made, tmp_path):
    """A journal of the old design, or a file named like the new temporaries, is never
    read, replaced or removed; the victim it names keeps its bytes."""
    folder = tmp_path / "shared"
    folder.mkdir()
    (folder / "victim.txt").write_text("the user's own file\n")
    (folder / ".victim.txt.bak").write_text("attacker\n")
    host = hashlib.sha256(socket.gethostname().encode()).hexdigest()[:8]
    journal = {"final": "victim.txt", "backup": ".victim.txt.bak", "files": ["victim.txt"]}
    for name in ("r.png", "victim.txt"):
        (folder / f".{name}~tt{host}-999999999-abcd.set").write_text(json.dumps(journal))
    (folder / ".r.png.tt-000000000000.tmp.png").write_text("planted")
    (folder / ".r.png.tt-0123456789ab.tmp.png").symlink_to("victim.txt")
    (folder / ".p.ttproj.tt-aaaaaaaaaaaa.tmp.ttproj").symlink_to("victim.txt")
    before = digest(folder)
    proc = run("render", made / "p.ttproj", folder / "r.png")
    assert proc.returncode == 0, proc.stderr
    after = digest(folder)
    assert after.pop("r.png") and after == before


# -- outputs against inputs ----------------------------------------------------------

@pytest.mark.parametrize("layout", ["project_beside", "packed_beside"])
def test_convert_does_not_overwrite_its_photo(made, tmp_path, layout):
    """The photo is the colour map the output set would write: refused, photo unchanged."""
    photo = tmp_path / ("p_colour.jxl" if layout == "project_beside" else "q_colour.jxl")
    photo.write_bytes(encode_image(read_image(made / "photo.png")[..., :3], codec="jpegxl"))
    before = digest(tmp_path)
    extra = [] if layout == "project_beside" else ["--packed", tmp_path / "q.ttpack"]
    refused(run("convert", photo, tmp_path / "p.ttproj", *extra), "input")
    assert digest(tmp_path) == before


# -- full disk (root: a tmpfs) --------------------------------------------------------

@contextlib.contextmanager
def small_disk(tmp_path: Path, size: str, left: int, old: str):
    """A tmpfs of ``size`` (mount's -o size=) at tmp_path/disk holding ``old`` (b'old'), filled
    up to ``left`` free bytes; skips without root or tmpfs."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(disk)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        (disk / old).write_bytes(b"old")
        free = os.statvfs(disk).f_bavail * os.statvfs(disk).f_frsize
        (disk / "filler").write_bytes(bytes(max(0, free - left)))
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)


@pytest.fixture
def full_disk(tmp_path):
    """A 300 KiB tmpfs with 4 KiB free, holding old.png (b'old')."""
    with small_disk(tmp_path, "300k", 4096, "old.png") as disk:
        yield disk


@pytest.mark.parametrize("command", [
    ["render", "{p}", "{d}/old.png"], ["render", "{p}", "{d}/r.tif"],
    ["render", "{p}", "{d}/r.exr"], ["convert", "{photo}", "{d}/c.ttproj"],
    ["export", "{p}", "{d}/ex", "--engine", "unity"],
    ["export", "{p}", "{d}/gis", "--engine", "geotiff"],
    ["pack", "{photo}", "{d}/x.ttpack", "--reduce-palette"],
], ids=lambda c: "-".join(c[:1] + c[2:3])[:40].replace("{d}/", ""))
def test_a_full_disk_is_one_line_and_no_half_file(made, full_disk, command):
    args = [a.format(p=made / "p.ttproj", photo=made / "photo.png", d=full_disk)
            for a in command]
    refused(run(*args))
    assert (full_disk / "old.png").read_bytes() == b"old"
    files = {p.name for p in full_disk.rglob("*") if p.is_file()}
    assert files == {"old.png", "filler"}, files


# -- cache entries ----------------------------------------------------------------------

def _forge(key: str, kind: str, arrays: dict, header: dict | None = None) -> bytes:
    """A disk-cache entry with a valid digest (core/io/disk_cache.py's layout)."""
    meta = header or {"key": key, "kind": kind,
                      "arrays": {n: [a.dtype.name, list(a.shape)] for n, a in arrays.items()}}
    text = json.dumps(meta).encode()
    body = (b"TTCACHE1" + struct.pack("<I", len(text)) + text
            + b"".join(a.tobytes() for a in arrays.values()))
    return body + hashlib.sha256(body).digest()


def _entry_arrays(path: Path) -> dict:
    from terratheme.core.io.disk_cache import DiskCache
    key, kind = path.name.split(".")
    return DiskCache(path.parent).load(key, kind, lambda a: {k: v.copy() for k, v in a.items()})


@pytest.fixture(scope="module")
def trained(made, tmp_path_factory):
    """classify with scribbles into a cache folder: (folder, args, labels' bytes)."""
    folder = tmp_path_factory.mktemp("trained")
    mask = np.zeros((96, 96), np.uint8)
    mask[5:30, 5:30], mask[60:90, 60:90], mask[5:30, 60:90] = 1, 2, 3
    write_image(folder / "mask.png", mask)
    args = ["classify", made / "photo.png", "--scribbles", folder / "mask.png",
            "-o", folder / "labels.png", "--cache-dir", folder / "cache"]
    proc = run(*args)
    assert proc.returncode == 0, proc.stderr
    return folder, args, (folder / "labels.png").read_bytes()


@pytest.mark.parametrize("damage", ["inf_features", "forged_shape"])
def test_a_bad_samples_entry_is_a_miss(trained, tmp_path, damage):
    folder, args, want = trained
    cache = tmp_path / "cache"
    cache.mkdir()
    (sample,) = (folder / "cache").glob("*.samples")
    key = sample.name[:64]
    arrays = _entry_arrays(sample)
    if damage == "inf_features":
        arrays["features"][0, 0] = np.inf
        data = _forge(key, "samples", arrays)
    else:  # 4e9 rows declared, none there
        data = _forge(key, "samples", {}, header={
            "key": key, "kind": "samples", "arrays": {
                "features": ["float32", [4_000_000_000, arrays["features"].shape[1]]],
                "labels": ["uint8", [4_000_000_000]]}})
    (cache / sample.name).write_bytes(data)
    args = [*args[:-1], cache]
    for _ in range(2):  # the second run finds a good entry again
        proc = run(*args)
        assert proc.returncode == 0, proc.stderr
        assert (folder / "labels.png").read_bytes() == want
    assert (cache / sample.name).read_bytes() != data


def test_cache_size_of_400_nines_is_one_line(made, tmp_path):
    refused(run("classify", made / "photo.png", "-o", tmp_path / "l.png", "--cache-dir",
                tmp_path / "c", "--cache-size", "9" * 400), "--cache-size")
    assert not (tmp_path / "l.png").exists()


def test_a_fifo_family_entry_does_not_block_perspective(made, tmp_path):
    cache = tmp_path / "families"
    args = ["perspective", made / "p_preview.png", tmp_path / "o.png", "--size", "64x36",
            "--cache-dir", cache]
    assert run(*args).returncode == 0
    (entry,) = cache.glob("*.family")
    want = read_image(tmp_path / "o.png")
    entry.unlink()
    os.mkfifo(entry)
    proc = run(*args, timeout=120)
    assert proc.returncode == 0, proc.stderr
    np.testing.assert_array_equal(read_image(tmp_path / "o.png"), want)


# -- model files -------------------------------------------------------------------------

#: OpenCV YAML whose empty base64 block made cv2.FileStorage spin for good
SPINNING_YAML = b"%YAML:1.0\n---\na: !!binary |\n  ICAgICAgICAgICAgICAgICAgICAgICAg\n"


@pytest.mark.parametrize("members", [("meta.json", "forest.yml"),
                                     ("meta.json", "forest.npz", "forest.yml")])
@pytest.mark.parametrize("command", ["classify", "convert"])
def test_a_model_with_opencv_yaml_is_one_line(made, trained, tmp_path, members, command):
    folder = trained[0]
    (model,) = (folder / "cache").glob("*.model")
    meta = zipfile.ZipFile(_model_file(model, tmp_path)).read("meta.json")
    bad = tmp_path / "bad.model"
    with zipfile.ZipFile(bad, "w") as zf:
        zf.writestr("meta.json", meta)
        if "forest.npz" in members:
            zf.writestr("forest.npz", zipfile.ZipFile(_model_file(model, tmp_path))
                        .read("forest.npz"))
        zf.writestr("forest.yml", SPINNING_YAML)
    out = ["-o", tmp_path / "l.png"] if command == "classify" else [tmp_path / "o.ttproj"]
    refused(run(command, made / "photo.png", *out, "--model", bad, timeout=120), "bad.model")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.model", "m.model"]


def _model_file(entry: Path, tmp_path: Path) -> Path:
    """The model file a cache entry holds, written out."""
    path = tmp_path / "m.model"
    if not path.exists():
        path.write_bytes(_entry_arrays(entry)["model"].tobytes())
    return path


# -- FIFOs as inputs ---------------------------------------------------------------------

@pytest.mark.parametrize("command", [
    ["convert", "{f}.png", "{o}.ttproj"],
    ["convert", "{photo}", "{o}.ttproj", "--scribbles", "{f}.png"],
    ["new", "{f}.png", "{o}.ttproj", "--themes", "water,sand"],
    ["new", "{f}.exr", "{o}.ttproj", "--themes", "water,sand", "--from", "terrain3d"],
    ["new", "{labels}", "{f}.png", "{o}.ttproj", "--themes", "water,sand", "--from", "weights"],
    ["pack", "{f}.png", "{o}.ttpack"],
    ["perspective", "{f}.png", "{o}.png"],
    ["perspective", "{f}.ttproj", "{o}.png"],
    ["classify", "{f}.png", "-o", "{o}.png"],
    ["app", "{f}.png", "--screenshot", "{o}.png"],
    ["app", "{f}.ttproj", "--screenshot", "{o}.png"],
], ids=lambda c: "-".join(c[:1] + [a.split("}")[-1] for a in c[1:3]]))
def test_a_fifo_input_is_one_line_not_a_hang(made, tmp_path, command):
    for ext in (".png", ".exr", ".ttproj"):
        os.mkfifo(tmp_path / f"f{ext}")
    args = [a.format(f=tmp_path / "f", o=tmp_path / "o", photo=made / "photo.png",
                     labels=made / "labels.png") for a in command]
    refused(run(*args, env={"QT_QPA_PLATFORM": "offscreen"}, timeout=120), "named pipe")
    assert not list(tmp_path.glob("o*"))


# -- --scheduler to something that is not a dask scheduler ---------------------------------

def _server(reply: bytes | None) -> tuple[int, threading.Event]:
    """A server on 127.0.0.1 that answers every connection with ``reply`` (None: never
    answers, keeps it open); it stops when the returned event is set (or after 120 s)."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(16)
    sock.settimeout(0.5)
    stop, held = threading.Event(), []

    def serve():
        end = time.monotonic() + 120
        while not stop.is_set() and time.monotonic() < end:
            try:
                conn, _ = sock.accept()
            except OSError:
                continue
            if reply is None:
                held.append(conn)
                continue
            conn.settimeout(2)
            try:
                conn.recv(65536)
                conn.sendall(reply)
            except OSError:
                pass
            conn.close()
        for conn in held:
            conn.close()
        sock.close()

    threading.Thread(target=serve, daemon=True).start()
    return sock.getsockname()[1], stop


@pytest.mark.parametrize("reply", [
    pytest.param(b"HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\nhello" + b"\xff" * 65536,
                 id="http"),
    pytest.param(None, id="silent", marks=pytest.mark.slow),
])
def test_scheduler_that_is_not_dask_is_one_line(made, tmp_path, reply):
    port, stop = _server(reply)
    try:
        proc = run("convert", made / "photo.png", tmp_path / "s.ttproj", "--tile", "64",
                   "--scheduler", f"tcp://127.0.0.1:{port}", timeout=90)
    finally:
        stop.set()
    refused(proc, f"127.0.0.1:{port}")
    assert not list(tmp_path.iterdir())


# -- symlink loops --------------------------------------------------------------------------

@pytest.mark.parametrize("command", [
    ["convert", "{loop}", "{t}/o.ttproj"], ["convert", "{photo}", "{t}/loopd/o.ttproj"],
    ["convert", "{photo}", "{t}/o.ttproj", "--preview", "{loop}"],
    ["render", "{loop}", "{t}/o.png"], ["render", "{p}", "{loop}"],
    ["export", "{p}", "{loop}", "--engine", "unity"],
    ["pack", "{loop}", "{t}/o.ttpack"], ["unpack", "{pack}", "{loop}"],
    ["classify", "{photo}", "-o", "{loop}"], ["perspective", "{photo}", "{loop}"],
    ["new", "{labels}", "{loop}", "--themes", "water,sand,town"], ["info", "{loop}"],
    ["app", "{photo}", "--screenshot", "{loop}"],
], ids=lambda c: "-".join(c[:1] + [a.strip("{}") for a in c[1:3]]))
def test_a_symlink_loop_is_one_line(made, tmp_path, command):
    (tmp_path / "loop").symlink_to("loop2")
    (tmp_path / "loop2").symlink_to("loop")
    (tmp_path / "loopd").symlink_to("loopd")
    args = [a.format(loop=tmp_path / "loop", t=tmp_path, photo=made / "photo.png",
                     p=made / "p.ttproj", pack=made / "p.ttpack", labels=made / "labels.png")
            for a in command]
    refused(run(*args, env={"QT_QPA_PLATFORM": "offscreen"}), "symlink loop")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loop", "loop2", "loopd"]


# -- unbounded work -------------------------------------------------------------------------

def _rewrite_project(src: Path, dst: Path, change, extra: dict | None = None,
                     drop: tuple = ()) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        manifest = json.loads(zin.read("manifest.json"))
        change(manifest)
        zout.writestr("manifest.json", json.dumps(manifest))
        for name in zin.namelist():
            if name != "manifest.json" and name not in drop:
                zout.writestr(name, zin.read(name))
        for name, data in (extra or {}).items():
            zout.writestr(name, data)
    return dst


@pytest.mark.parametrize("case", ["tile_1_one_member_per_pixel", "jxl_16384_declared"])
@pytest.mark.parametrize("command", ["info", "render"])
def test_a_colour_map_that_would_cost_minutes_is_refused_at_once(made, tmp_path, case,
                                                                   command):
    src = made / "p.ttproj"
    with zipfile.ZipFile(src) as zf:
        cmap = json.loads(zf.read("manifest.json"))["colour_map"]
        h, w = read_image(made / "photo.png").shape[:2]
        gh, gw = -(-h // cmap["scale"]), -(-w // cmap["scale"])
    if case.startswith("tile"):
        def change(m):
            m["version"] = 2
            m["colour_map"] = {"scale": cmap["scale"], "codec": cmap["codec"], "tile": 1,
                               "members": [cmap["member"]] * (gh * gw)}
        bad = _rewrite_project(src, tmp_path / "bad.ttproj", change)
    else:
        bad = _rewrite_project(src, tmp_path / "bad.ttproj", lambda m: None,
                               {cmap["member"]: bare_codestream(16384, 16384)},
                               drop=(cmap["member"],))
    out = [tmp_path / "o.png"] if command == "render" else []
    t0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    refused(run(command, bad, *out, timeout=120), "bad.ttproj")
    t1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    # CPU seconds, not wall time: the work itself must be bounded (it took minutes)
    assert (t1.ru_utime - t0.ru_utime) < 30
    assert not (tmp_path / "o.png").exists()


def _zero_png(path: Path, width: int, height: int, colour_type: int, channels: int) -> None:
    """An all-zero 8-bit PNG written row by row (a few hundred KB for 11585^2)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data)))
    z = zlib.compressobj(9)
    row = bytes(1 + width * channels)
    parts = [z.compress(row) for _ in range(height)] + [z.flush()]
    path.write_bytes(b"\x89PNG\r\n\x1a\n"
                     + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, colour_type,
                                                  0, 0, 0))
                     + chunk(b"IDAT", b"".join(parts)) + chunk(b"IEND", b""))


def _peak_rss_mib(proc_args: list, timeout: float = 600) -> tuple[subprocess.CompletedProcess,
                                                                    float]:
    """Run the CLI in a child whose peak RSS (MiB) is reported by a wrapper."""
    code = textwrap.dedent("""
        import resource, subprocess, sys
        p = subprocess.run(sys.argv[1:], capture_output=True)
        sys.stdout.buffer.write(p.stdout)
        sys.stderr.buffer.write(p.stderr)
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        sys.stdout.write(f"\\nPEAK {peak:.0f} {p.returncode}\\n")
    """)
    proc = subprocess.run(
        [sys.executable, "-c", code, sys.executable, "-m", "terratheme.app.cli",
         *map(str, proc_args)], capture_output=True, text=True, timeout=timeout, cwd=REPO,
        env=dict(os.environ, PYTHONPATH=str(REPO)))
    peak, code_ = proc.stdout.rsplit("PEAK ", 1)[1].split()
    return (subprocess.CompletedProcess(proc.args, int(code_), proc.stdout, proc.stderr),
            float(peak))


@pytest.mark.slow
def test_an_all_zero_11585_splatmap_is_bounded(tmp_path):
    """It took 1.9 GB (the map decoded whole, several copies); its grid is 134 MB."""
    _zero_png(tmp_path / "splat.png", 11585, 11585, 6, 4)
    proc, peak = _peak_rss_mib(["new", tmp_path / "splat.png", tmp_path / "s.ttproj",
                                "--themes", "water,sand,forest,town", "--from", "splatmap"])
    if proc.returncode != 0:
        refused(proc)
    assert peak < 1024, peak


def test_weight_maps_of_two_sizes_are_compared_before_reading(made, tmp_path):
    """The second map (11585^2 declared) is not read whole (462 MB) before the sizes differ."""
    _zero_png(tmp_path / "w2.png", 11585, 11585, 0, 1)
    proc, peak = _peak_rss_mib(["new", made / "labels.png", tmp_path / "w2.png",
                                tmp_path / "w.ttproj", "--themes", "water,sand",
                                "--from", "weights"])
    refused(proc, "w2.png")
    assert peak < 400, peak
    assert not (tmp_path / "w.ttproj").exists()


def test_a_two_channel_weight_map_is_refused(made, tmp_path):
    from PIL import Image
    Image.fromarray(np.zeros((40, 40, 2), np.uint8), "LA").save(tmp_path / "w2.png")
    refused(run("new", made / "labels.png", tmp_path / "w2.png", tmp_path / "w.ttproj",
                "--themes", "water,sand", "--from", "weights"), "w2.png", "2 channels")
    assert not (tmp_path / "w.ttproj").exists()


# -- mixed sets ---------------------------------------------------------------------------

def _kill_at_replace(k: int, signum: int) -> str:
    """Python run before the CLI: the process signals itself at its k-th os.replace."""
    return textwrap.dedent(f"""
        import os
        _replace, _calls = os.replace, [0]
        def _patched(a, b, **kw):
            _calls[0] += 1
            if _calls[0] == {k}:
                os.kill(os.getpid(), {int(signum)})
            return _replace(a, b, **kw)
        os.replace = _patched
    """)


def _unity_consistent(folder: Path) -> str:
    """'old' / 'new' / 'none' (no manifest); fails if the manifest's size and a map's differ."""
    manifest = folder / "terratheme_unity.json"
    if not manifest.exists():
        return "none"
    m = json.loads(manifest.read_text())
    for tile in m["tiles"]:
        for name in tile["splatmaps"]:
            shape = read_image(folder / name).shape[:2]
            assert list(shape[::-1]) == m["map_size"], (name, shape, m["map_size"])
    return "new" if m["map_size"] == [512, 512] else "old"


def _kill_cases(slow_all: bool):
    cases = [(k, s) for s in (signal.SIGKILL, signal.SIGTERM) for k in range(1, 12)]
    return cases if slow_all else [(1, signal.SIGKILL), (2, signal.SIGTERM),
                                   (4, signal.SIGKILL)]


@pytest.mark.parametrize(("k", "signum"), _kill_cases(False))
def test_a_killed_unity_export_never_mixes_sizes(made, tmp_path, k, signum):
    _export_killed(made, tmp_path, k, signum)


@pytest.mark.slow
@pytest.mark.parametrize(("k", "signum"), _kill_cases(True))
def test_a_killed_unity_export_never_mixes_sizes_every_rename(made, tmp_path, k, signum):
    _export_killed(made, tmp_path, k, signum)


def _export_killed(made, tmp_path, k, signum):
    out = tmp_path / "unity"
    first = run("export", made / "p.ttproj", out, "--engine", "unity", "--size", "1024x1024")
    assert first.returncode == 0, first.stderr
    assert _unity_consistent(out) == "old"
    proc = run("export", made / "p.ttproj", out, "--engine", "unity", "--size", "512x512",
               prefix=_kill_at_replace(k, signum))
    state = _unity_consistent(out)
    if proc.returncode == 0:  # fewer renames than k
        assert state == "new"
    else:
        assert proc.returncode == -signum, proc.stderr[-2000:]
        if signum == signal.SIGTERM:
            assert not temporaries(out)


def test_a_planted_old_manifest_removes_nothing(made, tmp_path):
    """The old set's manifest is input too: files it names that the new export does not
    write (outside the folder, the user's notes, a tile name) are left alone."""
    first = tmp_path / "first"
    assert run("export", made / "p.ttproj", first, "--engine", "unity").returncode == 0
    manifest = json.loads((first / "terratheme_unity.json").read_text())
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "victim.txt").write_text("victim")
    (out / "notes.txt").write_text("notes")
    (out / "splatmap_9.png").write_text("mine")
    manifest["tiles"][0]["splatmaps"] += ["../victim.txt", "notes.txt", "splatmap_9.png",
                                          str(tmp_path / "victim.txt")]
    manifest["project"] = "../victim.txt"
    manifest["colour_map"]["file"] = "notes.txt"
    (out / "terratheme_unity.json").write_text(json.dumps(manifest))
    proc = run("export", made / "p.ttproj", out, "--engine", "unity", "--size", "512x512")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "victim.txt").read_text() == "victim"
    assert (out / "notes.txt").read_text() == "notes"
    assert (out / "splatmap_9.png").read_text() == "mine"
    assert _unity_consistent(out) == "new"


def test_convert_colour_map_off_drops_the_old_colour_map(made, tmp_path):
    photo = tmp_path / "photo.png"
    photo.write_bytes((made / "photo.png").read_bytes())
    assert run("convert", photo, tmp_path / "p.ttproj").returncode == 0
    assert (tmp_path / "p_colour.avif").exists()
    (tmp_path / "q_colour.avif").write_bytes(b"the user's own")
    proc = run("convert", photo, tmp_path / "p.ttproj", "--colour-map", "off")
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "p_colour.avif").exists()
    assert (tmp_path / "q_colour.avif").read_bytes() == b"the user's own"
    with zipfile.ZipFile(tmp_path / "p.ttproj") as zf:
        assert "colour_map" not in json.loads(zf.read("manifest.json"))


# -- memory limits, options, Editor/, legends, codec scratch ----------------------------------

@pytest.mark.parametrize("mib", [300, 512, 1024])
@pytest.mark.parametrize("command", [
    ["convert", "{photo}", "{t}/o.ttproj"], ["render", "{p}", "{t}/o.png"],
    ["perspective", "{photo}", "{t}/o.png", "--no-cache"],
    ["classify", "{photo}", "-o", "{t}/o.png"], ["export", "{p}", "{t}/e", "--engine", "unity"],
    ["pack", "{labels}", "{t}/o.ttpack"],
    # info of a project was let run from 256 MiB: SIGSEGV at 500-600, scipy's OpenBLAS
    # spinning for good (SIGTERM ignored) at 650-700, exit 1 at 960
    ["info", "{p}"],
], ids=lambda c: c[0])
def test_below_the_memory_a_command_needs_is_one_line(made, tmp_path, command, mib):
    args = " ".join(f"'{a}'" for a in (a.format(photo=made / "photo.png", t=tmp_path,
                                                 p=made / "p.ttproj", labels=made / "labels.png")
                                       for a in command))
    proc = subprocess.run(
        ["bash", "-c", f"ulimit -v {mib << 10}; exec '{sys.executable}' -m "
                       f"terratheme.app.cli {args}"],
        capture_output=True, text=True, timeout=300, cwd=REPO,
        env=dict(os.environ, PYTHONPATH=str(REPO)))
    refused(proc, "ulimit -v")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("mib", [1500, 1600])
def test_convert_just_above_its_floor_is_one_line(made, tmp_path, mib):
    """Threads that cannot start and OpenCV's std::bad_alloc were tracebacks with exit 1."""
    proc = subprocess.run(
        ["bash", "-c", f"ulimit -v {mib << 10}; exec '{sys.executable}' -m terratheme.app.cli "
                       f"convert '{made / 'photo.png'}' '{tmp_path / 'o.ttproj'}'"],
        capture_output=True, text=True, timeout=300, cwd=REPO,
        env=dict(os.environ, PYTHONPATH=str(REPO)))
    if proc.returncode != 0:
        refused(proc)
        assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("exc", [
    RuntimeError("can't start new thread"),
    pytest.param("cv2", id="cv2_bad_alloc"),
])
def test_memory_failures_of_native_code_are_one_line(monkeypatch, capsys, exc):
    import cv2
    import terratheme.app.commands.themes
    from terratheme.app.cli import main
    if exc == "cv2":
        exc = cv2.error("OpenCV(5.1.0) std::bad_alloc")

    def fail(args):
        raise exc

    monkeypatch.setattr(terratheme.app.commands.themes, "run", fail)
    assert main(["themes"]) == 2
    err = capsys.readouterr().err
    assert err == "terratheme themes: error: not enough memory for this input\n"


def test_other_runtime_errors_are_not_taken_for_memory(monkeypatch):
    import terratheme.app.commands.themes
    from terratheme.app.cli import main

    def fail(args):
        raise RuntimeError("a bug")

    monkeypatch.setattr(terratheme.app.commands.themes, "run", fail)
    with pytest.raises(RuntimeError, match="a bug"):
        main(["themes"])


@pytest.mark.parametrize("args", [
    ["render", "{p}", "{t}/o.png", "--scale", "nan"],
    ["render", "{p}", "{t}/o.png", "--region", "1,2"],
    ["render", "{p}", "{t}/o.png", "--bogus"],
    ["convert", "{p}", "{t}/o.ttproj", "--cell", "-3"],
    ["convert", "{p}", "{t}/o.ttproj", "--colour-map", "1e400"],
    ["export", "{p}", "{t}/e", "--engine", "bogus"],
    ["pack", "{p}", "{t}/o.ttpack", "--tile", "3"],
    ["perspective", "{p}", "{t}/o.png", "--camera", "a,b"],
    ["render"],
], ids=lambda a: "-".join(a[:1] + a[3:4]))
def test_a_bad_option_value_is_one_line_not_usage(made, tmp_path, args):
    proc = run(*(a.format(p=made / "p.ttproj", t=tmp_path) for a in args))
    refused(proc)
    assert "usage:" not in proc.stderr


def test_export_does_not_write_through_a_symlinked_editor_folder(made, tmp_path):
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "TerrathemeImporter.cs").write_text("mine")
    out = tmp_path / "out"
    out.mkdir()
    (out / "Editor").symlink_to(victim)
    refused(run("export", made / "p.ttproj", out, "--engine", "unity"), "Editor")
    assert digest(victim) == {"TerrathemeImporter.cs": hashlib.sha256(b"mine").hexdigest()}


@pytest.mark.parametrize("text", [
    '{"\u0661": "Building", "2": "Road"}', '{"1_0": "Building"}',
    '[{"id": "1_0", "name": "B"}]',
    # A first CSV line with a digit is a value, not a header to skip (it was dropped).
    "\u0661,Building\n2,Road\n", "1_0,Building\n2,Road\n", "\uff11,Building\n2,Road\n",
    "-1,Building\n2,Road\n",
    # Past Python's 4300-digit int() limit: one line, not its ValueError.
    '{"' + "1" * 5000 + '": "Building"}', "1" * 5000 + ",Building\n2,Road\n",
    "0" * 4990 + "256,Building\n",
])
def test_legend_class_values_are_ascii_numbers(text):
    with pytest.raises(CorruptFileError, match="class value"):
        parse_legend(text.encode(), "legend.csv")


def test_a_csv_header_line_is_still_skipped():
    assert parse_legend(b"id,name\n1,Building\n2,Road\n", "l.csv") == {1: "Building", 2: "Road"}


def test_a_legend_with_an_arabic_digit_is_one_line_from_the_cli(made, trained, tmp_path):
    (tmp_path / "legend.csv").write_text("\u0661,Building\n2,Road\n", encoding="utf-8")
    refused(run("classify", made / "photo.png", "--scribbles", trained[0] / "mask.png",
                "-o", tmp_path / "o.png", "--legend", tmp_path / "legend.csv"), "legend.csv")
    assert not (tmp_path / "o.png").exists()


def test_a_run_killed_while_coding_an_image_leaves_no_scratch_file(made, tmp_path):
    """SIGKILL while a codec's scratch file is open: nothing named terratheme-codec-* stays."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    prefix = textwrap.dedent("""
        import os, signal
        import terratheme.core.io.codec as codec
        def _die(fd):
            os.kill(os.getpid(), signal.SIGKILL)
        codec._read_all = _die
    """)
    proc = run("convert", made / "photo.png", tmp_path / "o.ttproj", prefix=prefix,
               env={"TMPDIR": str(scratch)})
    assert proc.returncode == -signal.SIGKILL, proc.stderr[-2000:]
    assert not list(scratch.iterdir())


# -- the local dask cluster ---------------------------------------------------------------

def _tree(pid: int) -> set[int]:
    kids: dict[int, list[int]] = {}
    for line in subprocess.run(["ps", "-e", "-o", "pid=,ppid="], capture_output=True,
                               text=True).stdout.splitlines():
        a, b = map(int, line.split())
        kids.setdefault(b, []).append(a)
    out, i = [pid], 0
    while i < len(out):
        out += kids.get(out[i], [])
        i += 1
    return set(out)


_ATTACH = textwrap.dedent("""
    import os, sys
    from distributed import Client
    from distributed.security import Security
    address, scheme = sys.argv[1], sys.argv[2]
    security = Security.temporary() if scheme == "tls" else None
    try:
        client = Client(f"{scheme}://{address}", timeout=5, security=security)
        print("ATTACHED", client.run_on_scheduler(os.getuid))
    except BaseException as exc:
        print("refused", type(exc).__name__)
""")


@pytest.mark.slow
def test_the_local_cluster_takes_no_stranger_and_serves_no_dashboard(tmp_path):
    """A plain or another TLS client is refused by every port the run listens on; no port
    answers HTTP; every port is on 127.0.0.1."""
    import shutil
    import urllib.request
    if shutil.which("ss") is None or not SAMPLE.exists():
        pytest.skip("needs ss and the sample photo")
    proc = subprocess.Popen(
        [sys.executable, "-m", "terratheme.app.cli", "convert", "--tile", "256", "--workers",
         "2", str(SAMPLE), str(tmp_path / "d.ttproj")], cwd=REPO,
        env=dict(os.environ, PYTHONPATH=str(REPO)), stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)
    seen: set[str] = set()
    attached, answered = [], []
    try:
        while proc.poll() is None:
            pids = _tree(proc.pid)
            listing = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True).stdout
            for line in listing.splitlines():
                if not any(int(p) in pids for p in re.findall(r"pid=(\d+)", line)):
                    continue
                address = line.split()[3]
                if address in seen:
                    continue
                seen.add(address)
                assert address.startswith("127.0.0.1:"), line
                for scheme in ("tcp", "tls"):
                    try:
                        out = subprocess.run([sys.executable, "-c", _ATTACH, address, scheme],
                                             capture_output=True, text=True,
                                             timeout=30).stdout
                    except subprocess.TimeoutExpired:
                        out = "timed out"
                    if "ATTACHED" in out:
                        attached.append((address, scheme, out))
                try:
                    with urllib.request.urlopen(f"http://{address}/status", timeout=3) as r:
                        answered.append((address, r.status))
                except Exception:
                    pass
            time.sleep(0.2)
        _, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err.decode(errors="replace")[-2000:]
    assert seen, "no listening port seen: the check did not run"
    assert not attached and not answered, (attached, answered)
