"""Outputs never lose a user's file (issue 33): full disks, outputs that are inputs,
stale members of a set, symlinked output folders, killed exports, codec scratch files."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import types
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.io import images
from terratheme.core.io.images import read_image, write_image
from terratheme.core.model.project import load_project

REPO = Path(__file__).resolve().parents[1]
THEMES = "water,sand,forest"


def _photo(h=48, w=64, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 3), np.float64)
    img[:, : w // 2] = (40, 90, 200)
    img[:, w // 2:] = (225, 200, 140)
    return np.clip(img + rng.normal(0, 6, img.shape), 0, 255).astype(np.uint8)


def _one_line_error(capsys, argv, *needles) -> None:
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    # (Progress may print a line per finished stage before it.)
    last = err.rstrip("\n").rsplit("\n", 1)[-1]
    assert "Traceback" not in err and err.count(": error: ") == 1 and ": error: " in last, err
    for needle in needles:
        assert needle in last, err


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


@pytest.fixture
def project(tmp_path) -> Path:
    """A project made by ``new``: 8 x 8 vertices, cell 9, three themes."""
    grid = np.random.default_rng(3).integers(0, 3, (8, 8)).astype(np.uint8)
    write_image(tmp_path / "index.png", grid[:, :, None])
    path = tmp_path / "p.ttproj"
    assert main(["new", str(tmp_path / "index.png"), str(path), "--themes", THEMES,
                 "--cell", "9"]) == 0
    return path


# -- full disk -------------------------------------------------------------------

class _FailingClose:
    """An ImageOutput whose close reports failure (as on a full disk)."""

    def __init__(self, real):
        self._real = real

    def __getattr__(self, name):
        return getattr(self._real, name)

    def close(self):
        self._real.close()
        return False


def test_a_failing_close_keeps_the_old_image_and_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "out.png"
    write_image(target, np.zeros((4, 4, 3), np.uint8))
    before = target.read_bytes()
    fake = types.SimpleNamespace(**{n: getattr(oiio, n) for n in dir(oiio)
                                    if not n.startswith("__")})
    fake.ImageOutput = types.SimpleNamespace(
        create=lambda p: _FailingClose(oiio.ImageOutput.create(p)))
    monkeypatch.setattr(images, "oiio", fake)
    with pytest.raises(TerrathemeError, match="cannot write"):
        write_image(target, np.full((4, 4, 3), 9, np.uint8))
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]
    assert target.read_bytes() == before


@contextlib.contextmanager
def _small_disk(tmp_path: Path, size: str = "256k"):
    """A real tmpfs of ``size`` (root only; skips where it cannot be mounted)."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small filesystem needs root")
    folder = tmp_path / "disk"
    folder.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)],
                          capture_output=True)
    if done.returncode:
        pytest.skip(f"cannot mount a tmpfs: {done.stderr.decode(errors='replace').strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=False)


def _fill(folder: Path, leave: int) -> None:
    """Fill ``folder``'s filesystem until about ``leave`` bytes are free."""
    st = os.statvfs(folder)
    free = st.f_bavail * st.f_frsize
    (folder / "ballast").write_bytes(b"\0" * max(0, free - leave))


@pytest.mark.parametrize("ext", [".png", ".tif", ".exr", ".jpg", ".webp", ".jxl"])
def test_a_full_disk_is_an_error_and_keeps_the_old_image(tmp_path, ext):
    with _small_disk(tmp_path) as disk:
        target = disk / f"out{ext}"
        old = np.full((8, 8, 3), 7, np.float32 if ext == ".exr" else np.uint8)
        write_image(target, old)
        before = target.read_bytes()
        _fill(disk, 40_000)
        noise = np.random.default_rng(0).integers(0, 255, (300, 300, 3)).astype(old.dtype)
        np.save(tmp_path / "n.npy", noise)
        # In a subprocess: libjpeg ends the process on a full disk, the WebP writer hangs.
        code = f"""if True:
            import numpy as np
            from terratheme.core.errors import TerrathemeError
            from terratheme.core.io.images import write_image
            try:
                write_image({str(target)!r}, np.load({str(tmp_path / "n.npy")!r}))
            except TerrathemeError as exc:
                print("refused:", exc)
            """
        done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                              text=True, timeout=60, env=dict(os.environ, PYTHONPATH=str(REPO)))
        assert done.returncode == 0 and "refused: cannot write" in done.stdout, (
            done.returncode, done.stdout, done.stderr[-500:])
        assert target.read_bytes() == before
        assert sorted(p.name for p in disk.iterdir()) == ["ballast", f"out{ext}"]


def test_render_on_a_full_disk_exits_2_and_keeps_the_old_render(tmp_path, project, capsys):
    with _small_disk(tmp_path) as disk:
        out = disk / "render.png"
        assert main(["render", str(project), str(out)]) == 0
        before = out.read_bytes()
        _fill(disk, 2_000)
        _one_line_error(capsys, ["render", project, out], "cannot write")
        assert out.read_bytes() == before
        assert sorted(p.name for p in disk.iterdir()) == ["ballast", "render.png"]


# -- outputs that are inputs -----------------------------------------------------

def test_convert_never_overwrites_its_photo_with_the_colour_map(tmp_path, capsys):
    photo = tmp_path / "p_colour.jxl"
    write_image(photo, _photo())
    before = photo.read_bytes()
    _one_line_error(capsys, ["convert", photo, tmp_path / "p.ttproj", "--cell", "16"],
                    "is also an input")
    assert photo.read_bytes() == before and not (tmp_path / "p.ttproj").exists()


def test_convert_checks_the_packed_layer_s_colour_map_against_the_photo(tmp_path, capsys):
    photo = tmp_path / "q_colour.jxl"
    write_image(photo, _photo())
    before = photo.read_bytes()
    _one_line_error(capsys, ["convert", photo, tmp_path / "p.ttproj", "--cell", "16",
                             "--packed", tmp_path / "q.ttpack"], "q_colour.jxl", "input")
    assert photo.read_bytes() == before


def test_an_output_hard_linked_to_an_input_is_refused(tmp_path, capsys):
    photo = tmp_path / "photo.png"
    write_image(photo, _photo())
    os.link(photo, tmp_path / "p_preview.png")
    before = photo.read_bytes()
    _one_line_error(capsys, ["convert", photo, tmp_path / "p.ttproj", "--cell", "16"],
                    "is also an input")
    assert photo.read_bytes() == before


def test_render_s_world_file_is_checked_against_the_inputs(tmp_path, project, capsys):
    named = tmp_path / "r.pgw"  # a project file named as the render's world file would be
    named.write_bytes(project.read_bytes())
    _one_line_error(capsys, ["render", named, tmp_path / "r.png"], "r.pgw", "input")
    assert named.read_bytes() == project.read_bytes()


@pytest.mark.parametrize("where", ["output", "input"])
def test_a_symlink_loop_is_one_line(tmp_path, project, capsys, where):
    loop = tmp_path / "loop"
    loop.symlink_to(tmp_path / "loop")
    args = [project, loop / "x.png"] if where == "output" else [loop / "p.ttproj",
                                                                 tmp_path / "x.png"]
    _one_line_error(capsys, ["render", *args], "loop")


def test_export_refuses_a_symlinked_subfolder(tmp_path, project, capsys):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = tmp_path / "unity"
    out.mkdir()
    (out / "Editor").symlink_to(elsewhere)
    _one_line_error(capsys, ["export", project, out, "--engine", "unity"],
                    "symbolic link")
    assert list(elsewhere.iterdir()) == [] and [p.name for p in out.iterdir()] == ["Editor"]


# -- the set is exactly what the project names -----------------------------------

def test_colour_map_off_removes_the_old_set_s_colour_map(tmp_path):
    photo = tmp_path / "h.png"
    write_image(photo, _photo())
    proj = tmp_path / "p.ttproj"
    assert main(["convert", str(photo), str(proj), "--cell", "16"]) == 0
    assert (tmp_path / "p_colour.avif").exists()
    assert main(["convert", str(photo), str(proj), "--cell", "16", "--colour-map", "off"]) == 0
    assert load_project(proj).colour_map is None
    assert not (tmp_path / "p_colour.avif").exists()


def test_a_colour_map_file_that_is_not_the_old_set_s_stays(tmp_path):
    photo = tmp_path / "h.png"
    write_image(photo, _photo())
    proj = tmp_path / "p.ttproj"
    assert main(["convert", str(photo), str(proj), "--cell", "16"]) == 0
    mine = tmp_path / "p_colour.avif"
    mine.write_bytes(b"the user's own file")
    assert main(["convert", str(photo), str(proj), "--cell", "16", "--colour-map", "off"]) == 0
    assert mine.read_bytes() == b"the user's own file"


# -- an export killed part way ----------------------------------------------------

_EXPORT_CHILD = """
    import os, signal
    from pathlib import Path
    from terratheme.app.cli import main
    import terratheme.core.exchange.unity as unity
    import terratheme.core.io.atomic as atomic
    real_write, real_replace = unity.write_image, os.replace
    def write_then_die(*a, **k):
        real_write(*a, **k)
        if {during_work}:
            os.kill(os.getpid(), signal.SIGKILL)
    def replace_then_die(a, b):
        real_replace(a, b)
        if {during_renames} and Path(b).name.startswith("splatmap"):
            os.kill(os.getpid(), signal.SIGKILL)
    unity.write_image = write_then_die
    atomic.os.replace = replace_then_die
    main(["export", {project!r}, {out!r}, "--engine", "unity", "--size", "16x16"])
"""


@pytest.mark.parametrize("when", ["during the work", "during the renames"])
def test_a_killed_export_never_leaves_new_maps_under_the_old_manifest(tmp_path, project, when):
    out = tmp_path / "unity"
    assert main(["export", str(project), str(out), "--engine", "unity", "--size", "32x32"]) == 0
    before = _files(out)
    code = textwrap.dedent(_EXPORT_CHILD.format(
        project=str(project), out=str(out), during_work=when == "during the work",
        during_renames=when == "during the renames"))
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          env=dict(os.environ, PYTHONPATH=str(REPO)), timeout=120)
    assert done.returncode == -signal.SIGKILL, done.stderr.decode()[-800:]
    after = {k: v for k, v in _files(out).items() if not Path(k).name.startswith(".")}
    if when == "during the work":
        assert after == before  # the old export, whole
    else:
        assert "terratheme_unity.json" not in after  # no manifest: no set to trust
        assert read_image(out / "splatmap_0.png").shape[:2] == (16, 16)


# -- the codec's scratch files ---------------------------------------------------

def test_a_killed_codec_leaves_nothing_in_the_temp_folder(tmp_path):
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    done = subprocess.run([sys.executable, "-c", textwrap.dedent("""
        import os, signal
        import numpy as np
        import OpenImageIO as oiio
        import terratheme.core.io.codec as codec

        class Dying:  # killed while the image is being encoded
            @staticmethod
            def create(path):
                os.kill(os.getpid(), signal.SIGKILL)

        oiio.ImageOutput = Dying
        codec.encode_image(np.zeros((8, 8, 3), np.uint8), codec="png")
        """)], cwd=REPO, capture_output=True, timeout=60,
        env=dict(os.environ, PYTHONPATH=str(REPO), TMPDIR=str(scratch)))
    assert done.returncode == -signal.SIGKILL, done.stderr.decode()[-800:]
    assert list(scratch.iterdir()) == []
