"""Issue 33, round four: inputs the earlier rounds did not reach, through the CLI.

Each case runs the CLI in a subprocess (:func:`test_hostile_round2.run`) and checks what
a user sees: exit status 2 and one error line, no input or unnamed file changed, no
stale or half-written output. This round covers the inputs of the tiled path's cluster
(TLS certificate files), the side files of a render or a conversion (world files), photos
and model paths the classifier took wrongly, options that could not be honoured,
georeferences no output can carry, and outputs on a full disk (written by matplotlib, Qt
or libtiff, or as a member of convert's set).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from terratheme.core.io.images import write_image
from test_hostile_round2 import refused, run, small_disk


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> Path:
    """A folder with photo.png (24 x 24, three colours)."""
    folder = tmp_path_factory.mktemp("small")
    photo = np.zeros((24, 24, 3), np.uint8)
    photo[:12], photo[12:, :12], photo[12:, 12:] = (30, 80, 200), (40, 140, 40), (200, 190, 120)
    write_image(folder / "photo.png", photo)
    return folder


# -- certificate files that are no files ---------------------------------------------------

@pytest.mark.parametrize("which", ["ca", "cert", "key"])
def test_a_tls_file_that_is_a_fifo_is_one_line_not_a_hang(small, tmp_path, which):
    """OpenSSL opened --tls-ca-file with no check: a named pipe there blocked convert
    --scheduler tls://... for ever (--tls-cert and --tls-key were opened the same way)."""
    files = {name: tmp_path / f"{name}.pem" for name in ("ca", "cert", "key")}
    for name, path in files.items():
        if name == which:
            os.mkfifo(path)
        else:
            path.write_text("not a certificate\n")
    proc = run("convert", small / "photo.png", tmp_path / "o.ttproj", "--tile", "16",
               "--scheduler", "tls://127.0.0.1:9", "--tls-ca-file", files["ca"],
               "--tls-cert", files["cert"], "--tls-key", files["key"], timeout=60)
    refused(proc, f"{files[which]}: ", "named pipe")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ca.pem", "cert.pem", "key.pem"]


# -- side files left from an earlier output ------------------------------------------------

def _georeferenced_photo(folder: Path) -> Path:
    """photo.png of ``folder`` as a GeoTIFF with 0.5 m pixels at (500000, 4000000)."""
    import tifffile
    from terratheme.core.io.images import read_image

    photo = folder / "geo.tif"
    tifffile.imwrite(photo, read_image(folder / "photo.png"), photometric="rgb",
                     extratags=[(33550, "d", 3, [0.5, 0.5, 0.0], False),
                                (33922, "d", 6, [0, 0, 0, 5e5, 4e6, 0], False)])
    return photo


def test_a_render_without_georeference_leaves_no_world_file_of_the_old_one(small, tmp_path):
    """render r.png of a project without a georeference, over a render of a georeferenced
    one, kept the old r.pgw: GIS placed the new image where the old one was."""
    photo = _georeferenced_photo(small)
    for src, name in ((photo, "g.ttproj"), (small / "photo.png", "p.ttproj")):
        proc = run("convert", src, tmp_path / name, "--cell", "8", "--themes", "3")
        assert proc.returncode == 0, proc.stderr[-2000:]
    out = tmp_path / "out"
    out.mkdir()
    assert run("render", tmp_path / "g.ttproj", out / "r.png").returncode == 0
    assert (out / "r.pgw").read_text().split()[4:] == ["500000.25", "3999999.75"]
    (out / "mine.pgw").write_text("the user's own\n")  # a world file of no image rendered
    for name in ("r.png", "mine.png"):
        proc = run("render", tmp_path / "p.ttproj", out / name)
        assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(p.name for p in out.iterdir()) == ["mine.pgw", "mine.png", "r.png"]
    assert (out / "mine.pgw").read_text() == "the user's own\n"


def test_a_conversion_without_georeference_leaves_no_world_file_of_the_old_preview(
        small, tmp_path):
    """convert of a photo without a georeference onto a project converted from a GeoTIFF
    kept the old p_preview.pgw beside the new preview."""
    photo = _georeferenced_photo(small)
    for src in (photo, small / "photo.png"):
        proc = run("convert", src, tmp_path / "p.ttproj", "--cell", "8", "--themes", "3")
        assert proc.returncode == 0, proc.stderr[-2000:]
        if src == photo:
            assert (tmp_path / "p_preview.pgw").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "p.ttpack", "p.ttproj", "p_colour.avif", "p_preview.png"]


# -- photos of other pixel types -----------------------------------------------------------

@pytest.mark.parametrize("dtype", ["int32", "uint32"])
def test_classify_reads_a_32_bit_photo_as_convert_does(small, tmp_path, dtype):
    """A 32-bit integer photo converts, but classify refused it after reading it with
    'photo pixel type int32 is not supported', naming no file (with --train: which one?)."""
    import tifffile
    from terratheme.core.io.images import read_image, read_labels

    rgb = read_image(small / "photo.png")
    top = np.iinfo(dtype).max
    photo = tmp_path / "p32.tif"  # the same colours at 32 bits (255 -> the type's top)
    tifffile.imwrite(photo, (rgb.astype(np.int64) * top // 255).astype(dtype),
                     photometric="rgb")
    proc = run("classify", photo, "-o", tmp_path / "l.png", "--themes", "3")
    assert proc.returncode == 0, proc.stderr[-2000:]
    labels = read_labels(tmp_path / "l.png")
    # the insides of the photo's three colour blocks (the classifier smooths their borders)
    blocks = [labels[2:10, 2:22], labels[14:22, 2:10], labels[14:22, 14:22]]
    assert all(np.unique(b).size == 1 for b in blocks)
    assert len({int(b[0, 0]) for b in blocks}) == 3
    scribbles = np.zeros((24, 24), np.uint8)
    scribbles[2:5, 2:5], scribbles[15:18, 2:5], scribbles[15:18, 15:18] = 1, 2, 3
    write_image(tmp_path / "s.png", scribbles)
    proc = run("classify", small / "photo.png", "-o", tmp_path / "t.png", "--scribbles",
               tmp_path / "s.png", "--train", photo, tmp_path / "s.png")
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.parametrize("kind", ["fifo", "folder"])
@pytest.mark.parametrize("command", ["classify", "convert"])
def test_a_model_that_is_no_file_is_named_for_what_it_is(small, tmp_path, kind, command):
    """--model PIPE or --model FOLDER said 'no such model file, nor a shipped model' of a
    path that is there."""
    model = tmp_path / "m.ttmodel"
    if kind == "fifo":
        os.mkfifo(model)
    else:
        model.mkdir()
    out = ["-o", tmp_path / "l.png"] if command == "classify" else [tmp_path / "o.ttproj"]
    line = refused(run(command, small / "photo.png", *out, "--model", model, timeout=60),
                   f"{model}: ")
    assert ("named pipe" if kind == "fifo" else "is a folder") in line, line
    assert [p.name for p in tmp_path.iterdir()] == ["m.ttmodel"]


# -- options that could not be honoured ----------------------------------------------------

def test_convert_tile_refuses_the_curve_it_would_not_write(small, tmp_path):
    """convert --tile 16 --curve c.svg converted the photo tile by tile and exited 0 with
    no chart: the tiled path makes none and ignored the option."""
    proc = run("convert", small / "photo.png", tmp_path / "p.ttproj", "--tile", "16",
               "--curve", tmp_path / "c.svg")
    refused(proc, "--curve", "--tile")
    assert not proc.stderr.startswith("convert")  # no stage ran
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("name", ["s.xyz", "s"])
def test_a_screenshot_name_qt_cannot_write_is_refused_before_qt_starts(small, tmp_path, name):
    """app --screenshot s.xyz loaded the project, laid out the window and grabbed it, then
    said 'cannot write the screenshot s.xyz'."""
    proc = run("app", small / "photo.png", "--screenshot", tmp_path / "sub" / name,
               env={"QT_QPA_PLATFORM": "offscreen"}, timeout=120)
    refused(proc, f"{tmp_path / 'sub' / name}: ", ".png")
    assert not any(tmp_path.iterdir())


# -- georeferences no output can carry -----------------------------------------------------

@pytest.mark.parametrize("out", ["r.png", "r.tif"])
def test_render_refuses_a_georeference_no_gis_can_use_before_work(small, tmp_path, out):
    """A project whose georeference has a zero pixel size (hand-edited, or converted before
    round 3) rendered with exit 0: a world file or GeoTIFF tags of zero pixel size, which no
    GIS can place; every export of it refused."""
    import json
    import zipfile

    proc = run("convert", _georeferenced_photo(small), tmp_path / "g.ttproj", "--cell", "8",
               "--themes", "3")
    assert proc.returncode == 0, proc.stderr[-2000:]
    bad = tmp_path / "bad.ttproj"
    with zipfile.ZipFile(tmp_path / "g.ttproj") as zin, zipfile.ZipFile(bad, "w") as zout:
        for name in zin.namelist():
            data = zin.read(name)
            if name == "manifest.json":
                manifest = json.loads(data)
                manifest["metadata"]["georeference"]["ModelPixelScale"] = [0.0, 0.5, 0.0]
                data = json.dumps(manifest).encode()
            zout.writestr(name, data)
    folder = tmp_path / "out"
    folder.mkdir()
    refused(run("render", bad, folder / out), f"{bad}: ", "degenerate pixel size")
    assert not any(folder.iterdir())


# -- outputs lost to a full disk -----------------------------------------------------------

@pytest.mark.parametrize("suffix", [".pdf", ".svg"])
def test_the_curve_chart_lost_to_a_full_disk_is_one_line(small, tmp_path, suffix):
    """matplotlib's PDF writer, failing on a full disk, raised an AttributeError of its own
    ('Stream' object has no attribute 'pos'): convert --curve c.pdf was a traceback, exit 1."""
    with small_disk(tmp_path, "300k", 4096, "old.png") as disk:
        chart = disk / f"c{suffix}"
        refused(run("convert", small / "photo.png", tmp_path / "p.ttproj", "--curve", chart),
                f"{chart}: ", "No space left")
        assert sorted(p.name for p in disk.iterdir()) == ["filler", "old.png"]


@pytest.mark.parametrize("name", ["old.png", "s.png"])
def test_a_screenshot_lost_to_a_full_disk_keeps_the_old_file(small, tmp_path, name):
    """app --screenshot was saved by Qt straight onto its path: on a full disk it left a
    truncated 4 KiB PNG (old.png's bytes lost) and libpng's 'Write Error' line on stderr."""
    idx = np.zeros((9, 9), np.uint8)
    idx[4:] = 1
    write_image(tmp_path / "idx.png", idx)
    proc = run("new", tmp_path / "idx.png", tmp_path / "p.ttproj", "--themes", "water,sand")
    assert proc.returncode == 0, proc.stderr[-2000:]
    with small_disk(tmp_path, "300k", 4096, "old.png") as disk:
        proc = run("app", tmp_path / "p.ttproj", "--screenshot", disk / name,
                   env={"QT_QPA_PLATFORM": "offscreen"}, timeout=120)
        refused(proc, f"{disk / name}: ", "No space left")
        assert (disk / "old.png").read_bytes() == b"old"
        assert sorted(p.name for p in disk.iterdir()) == ["filler", "old.png"]


@pytest.mark.parametrize("command", [
    ["classify", "{photo}", "-o", "{t}/l.png", "--confidence", "{d}/c.tif"],
    ["unpack", "{l}", "{d}/u.tif"],
    ["render", "{p}", "{d}/r.tif", "--scale", "0.5"],
], ids=lambda c: c[0])
def test_a_tiff_lost_to_a_full_disk_names_the_disk_not_a_temporary(small, tmp_path, command):
    """libtiff reports a header it cannot write as 'Could not open': a TIFF output on a full
    disk was 'cannot write d/c.tif: Could not open "d/.c.tif.tt-0123456789ab.tmp.tif"'."""
    idx = np.zeros((9, 9), np.uint8)
    idx[4:] = 1
    write_image(tmp_path / "idx.png", idx)
    for args in (["pack", tmp_path / "idx.png", tmp_path / "l.ttpack"],
                 ["new", tmp_path / "idx.png", tmp_path / "p.ttproj", "--themes", "water,sand"]):
        proc = run(*args)
        assert proc.returncode == 0, proc.stderr[-2000:]
    with small_disk(tmp_path, "64k", 0, "old.png") as disk:
        args = [a.format(photo=small / "photo.png", t=tmp_path, d=disk, l=tmp_path / "l.ttpack",
                         p=tmp_path / "p.ttproj") for a in command]
        out = next(a for a in args if a.startswith(str(disk)))
        line = refused(run(*args), f"cannot write {out}: ", "disk is full")
        assert ".tt-" not in line, line
        assert sorted(p.name for p in disk.iterdir()) == ["filler", "old.png"]


@pytest.mark.parametrize("suffix", [".jpg", ".webp"])
def test_a_preview_lost_to_a_full_disk_names_the_preview(small, tmp_path, suffix):
    """convert wrote the preview to a temporary of its set's temporary: a full disk was
    'cannot write d/.p.jpg.tt-0123456789ab.tmp.jpg: 0 bytes free on its disk ...'."""
    with small_disk(tmp_path, "64k", 0, "old.png") as disk:
        preview = disk / f"p{suffix}"
        line = refused(run("convert", small / "photo.png", tmp_path / "p.ttproj", "--preview",
                           preview), f"cannot write {preview}: ")
        assert ".tt-" not in line, line
        assert sorted(p.name for p in disk.iterdir()) == ["filler", "old.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["disk"]  # no member of the set


# -- output names that end in '/' ------------------------------------------------------------

@pytest.mark.parametrize("command", [
    ["convert", "{photo}", "{d}/x.ttproj/"],
    ["convert", "{photo}", "{d}/x.ttproj", "--preview", "{d}/p.png/"],
    ["convert", "{photo}", "{d}/x.ttproj", "--curve", "{d}/c.svg/"],
    ["classify", "{photo}", "-o", "{d}/l.png/"],
], ids=["project", "preview", "curve", "labels"])
def test_an_output_name_ending_in_a_slash_is_refused(small, tmp_path, command):
    """convert x.ttproj/ wrote the file x.ttproj (Path drops the slash); render r.png/
    said no format is written as '.png'."""
    args = [a.format(photo=small / "photo.png", d=tmp_path) for a in command]
    refused(run(*args), "ends in '/'")
    assert not any(tmp_path.iterdir())


def test_an_image_and_its_world_file_are_replaced_together(tmp_path, monkeypatch):
    """render wrote the image, then its world file: a world file that could not be written
    (a full disk) left the new image placed by the old world file."""
    import terratheme.core.io.georef as georef_mod
    from terratheme.core.io.georef import write_georeferenced

    geo = {"ModelPixelScale": [1.0, 1.0, 0.0], "ModelTiepoint": [0, 0, 0, 100.0, 200.0, 0]}
    old = np.zeros((8, 8, 3), np.uint8)
    made = write_georeferenced(tmp_path / "r.png", old, geo)
    assert made == [tmp_path / "r.pgw"]
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def full(path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(georef_mod, "write_bytes_atomic", full)
    moved = {**geo, "ModelTiepoint": [0, 0, 0, 500.0, 600.0, 0]}
    with pytest.raises(OSError):
        write_georeferenced(tmp_path / "r.png", np.full((8, 8, 3), 255, np.uint8), moved)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_export_to_a_pipe_names_it_a_pipe(tmp_path):
    """export p FIFO said 'is a file, not an output folder'."""
    idx = np.zeros((5, 5), np.uint8)
    idx[2:] = 1
    write_image(tmp_path / "i.png", idx)
    proc = run("new", tmp_path / "i.png", tmp_path / "p.ttproj", "--themes", "water,sand")
    assert proc.returncode == 0, proc.stderr[-2000:]
    os.mkfifo(tmp_path / "out")
    refused(run("export", tmp_path / "p.ttproj", tmp_path / "out", "--engine", "godot"),
            "is a pipe, not an output folder")


@pytest.mark.parametrize("engine", ["godot", "unity"])
def test_an_export_folder_linked_to_nothing_is_named_so(tmp_path, engine):
    """export p DANGLING said 'cannot make the folder DANGLING (File exists)'."""
    idx = np.zeros((5, 5), np.uint8)
    idx[2:] = 1
    write_image(tmp_path / "i.png", idx)
    proc = run("new", tmp_path / "i.png", tmp_path / "p.ttproj", "--themes", "water,sand")
    assert proc.returncode == 0, proc.stderr[-2000:]
    (tmp_path / "out").symlink_to(tmp_path / "gone" / "away")
    refused(run("export", tmp_path / "p.ttproj", tmp_path / "out", "--engine", engine),
            "is a symlink to", "which does not exist")
    assert not (tmp_path / "gone").exists()
