"""Issue 33, round three: what the earlier hostile-input rounds missed, through the CLI.

Each case runs the CLI in a subprocess (:func:`test_hostile_round2.run`) and checks what
a user sees: exit status 2 and one error line, no input or unnamed file changed, no
half-written output. Cases that need root (a tmpfs that fills up) skip without it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from terratheme.core.io.images import write_image
from test_hostile_round2 import refused, run, small_disk


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> Path:
    """A folder with idx.png (a 9 x 9 index image of 3 themes), its project p.ttproj, its
    packed layer l.ttpack and photo.png (24 x 24, three colours)."""
    folder = tmp_path_factory.mktemp("small")
    idx = np.zeros((9, 9), np.uint8)
    idx[4:], idx[:, 6:] = 1, 2
    write_image(folder / "idx.png", idx)
    photo = np.zeros((24, 24, 3), np.uint8)
    photo[:12], photo[12:, :12], photo[12:, 12:] = (30, 80, 200), (40, 140, 40), (200, 190, 120)
    write_image(folder / "photo.png", photo)
    for args in (["new", folder / "idx.png", folder / "p.ttproj", "--themes", "water,sand,grass"],
                 ["pack", folder / "idx.png", folder / "l.ttpack"]):
        proc = run(*args)
        assert proc.returncode == 0, proc.stderr[-2000:]
    return folder


# -- a full disk that swallows a small image whole --------------------------------------

@pytest.fixture
def no_space(tmp_path):
    """A 64 KiB tmpfs with no byte free, holding old.exr (b'old')."""
    with small_disk(tmp_path, "64k", 0, "old.exr") as disk:
        yield disk


@pytest.mark.parametrize("command", [
    ["unpack", "{l}", "{d}/old.exr"],                  # the tiled writer
    ["unpack", "{l}", "{d}/u.exr"],
    ["render", "{p}", "{d}/r.png", "--scale", "0.05"],  # write_image
    ["render", "{p}", "{d}/r.bmp", "--scale", "0.05"],
    ["perspective", "{p}", "{d}/q.exr", "--size", "8x8", "--no-cache"],
], ids=lambda c: "-".join(c[:1] + c[2:3])[:40].replace("{d}/", ""))
def test_a_small_image_lost_to_a_full_disk_is_one_line(small, no_space, command):
    """OpenImageIO's file layer drops the error of the last buffered write: a small EXR or
    PNG on a full disk came out as 0 bytes with exit 0 (and replaced old.exr)."""
    args = [a.format(p=small / "p.ttproj", l=small / "l.ttpack", d=no_space)
            for a in command]
    refused(run(*args), "disk is full")
    assert (no_space / "old.exr").read_bytes() == b"old"
    files = {p.name for p in no_space.rglob("*") if p.is_file()}
    assert files == {"old.exr", "filler"}, files


@pytest.mark.parametrize("flag", ["-o", "--confidence"])
def test_classify_names_its_output_not_a_temporary_of_a_temporary(small, no_space, flag):
    """classify wrote each member of its set to a temporary of the set's temporary: a full
    disk was reported as 'cannot write .../.c.tif.tt-....tmp.tif'."""
    out = no_space / "c.tif"
    args = ["-o", out] if flag == "-o" else ["-o", no_space.parent / "l.png", flag, out]
    refused(run("classify", small / "photo.png", *args), f"cannot write {out}: ")
    assert {p.name for p in no_space.iterdir()} == {"old.exr", "filler"}


# -- numbers at their extremes ------------------------------------------------------------

@pytest.mark.parametrize("mapping", ["1e308,1e308,1e308,1e308,1e308,1e308,1e-308,1e-308,1e-308",
                                     "1e300,0,0,0,1e300,0,1e-300,0,1e-300"])
def test_a_finite_mapping_that_overflows_prints_no_warning(small, tmp_path, mapping):
    """Finite --mapping coefficients whose U, V overflow to inf rendered, with numpy's
    RuntimeWarnings (file, line and source) on stderr."""
    proc = run("perspective", small / "photo.png", tmp_path / "q.png", "--size", "8x8",
               "--no-cache", f"--mapping={mapping}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Warning" not in proc.stderr, proc.stderr[-2000:]
    assert (tmp_path / "q.png").is_file()


# -- names that reach the terminal ------------------------------------------------------

@pytest.mark.parametrize("name", ["e\x1b[2Jx.png", "t\x1b]0;title\x07.png", "r\u202egnp.png"])
def test_control_characters_of_a_file_name_are_escaped_in_the_error_line(small, tmp_path,
                                                                          name):
    """A file name from a folder (a shell glob) holding ESC [2J cleared the terminal when
    the error line quoted it; BEL, OSC and bidi overrides went out raw too."""
    bad = tmp_path / name
    bad.write_bytes(b"junk")
    for args in (["pack", bad, tmp_path / "o.ttpack"], ["render", tmp_path / ("m" + name),
                                                         tmp_path / "o.png"]):
        line = refused(run(*args))
        assert line.isprintable(), repr(line)
        assert repr(name[1])[1:-1] in line, line


# -- georeferences no export can use ------------------------------------------------------

@pytest.mark.parametrize("tags, needle", [
    ({33550: [0.0, 0.0, 0.0], 33922: [0, 0, 0, 5e5, 4e6, 0]}, "degenerate pixel size"),
    ({34264: [0.0] * 16}, "degenerate pixel size"),
    # Both pixel axes along (1, 1): a singular frame, not a zero one.
    ({34264: [1.0, 1.0, 0, 0, 1.0, 1.0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1.0]},
     "degenerate pixel size"),
    ({33550: [1e-320, 1e-320, 0.0], 33922: [0.0] * 6}, "beyond the range of floating-point"),
])
def test_convert_refuses_a_georeference_no_export_could_use_before_work(small, tmp_path,
                                                                         tags, needle):
    """A GeoTIFF photo with a zero pixel size (or a singular transformation, or a
    subnormal one) was converted; every export of the project then failed on it."""
    import tifffile
    from terratheme.core.io.images import read_image

    photo = tmp_path / "geo.tif"
    tifffile.imwrite(photo, read_image(small / "photo.png"), photometric="rgb",
                     extratags=[(code, "d", len(v), v, False) for code, v in tags.items()])
    out = tmp_path / "c.ttproj"
    refused(run("convert", photo, out, "--cell", "8", "--themes", "3"), f"{photo}: ", needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["geo.tif"]


# -- outputs that changed the values they promise -----------------------------------------

def _exr_round_trip(folder: Path, index: np.ndarray, stem: str) -> None:
    """pack a PNG of ``index``, unpack it to EXR, pack the EXR: every step exit 0."""
    write_image(folder / f"{stem}.png", index)
    for args in (["pack", folder / f"{stem}.png", folder / f"{stem}.ttpack"],
                 ["unpack", folder / f"{stem}.ttpack", folder / f"{stem}.exr"],
                 ["pack", folder / f"{stem}.exr", folder / f"{stem}_back.ttpack"]):
        proc = run(*args)
        assert proc.returncode == 0, proc.stderr[-2000:]


def test_unpack_to_exr_keeps_every_index_value(tmp_path):
    """EXR has no 8- or 16-bit integers: unpack wrote them as half floats scaled to 0..1,
    which merged 60000 and 60001 of a uint16 layer and read back as no label image."""
    from terratheme.core.io.images import read_labels
    from terratheme.core.packing import pack, pack_file

    index = np.full((16, 16), 1000, np.uint16)
    index[8:], index[:, 8:], index[:4, :4] = 60000, 60001, 65535
    _exr_round_trip(tmp_path, index, "i")
    np.testing.assert_array_equal(read_labels(tmp_path / "i.exr"), index)
    # ... and the EXR packs back to the same layer (pack refused its 32-bit integers), in
    # memory and band by band (a large file's path).
    assert (tmp_path / "i_back.ttpack").read_bytes() == (tmp_path / "i.ttpack").read_bytes()
    assert pack_file(tmp_path / "i.exr").to_bytes() == pack(index[:, :, None]).to_bytes()
    # A uint8 layer (theme indices) comes back as uint8: the same bytes.
    _exr_round_trip(tmp_path, (np.arange(16 * 16) % 7).astype(np.uint8).reshape(16, 16), "s")
    assert (tmp_path / "s_back.ttpack").read_bytes() == (tmp_path / "s.ttpack").read_bytes()


def test_pack_refuses_an_exr_index_beyond_16_bits(tmp_path):
    from terratheme.core.io.tiled_writer import TiledImageWriter

    # 32-bit UINT, as unpack writes an EXR index.
    index = np.full((8, 8, 1), 7, np.uint32)
    index[0, 0] = 70000
    with TiledImageWriter(tmp_path / "big.exr", 8, 8, 1, np.uint32, tile=8) as out:
        out.write(0, 0, index)
    refused(run("pack", tmp_path / "big.exr", tmp_path / "big.ttpack"), "70000", "16 bits")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.exr"]


def test_classify_labels_keep_their_class_numbers_or_are_refused(small, tmp_path):
    """classify -o l.jpg wrote the labels lossy (classes 0 and 6 appeared beside 1..5 on a
    real photo) and -o l.exr as half floats scaled to 0..1 (no label image any more)."""
    from terratheme.core.io.images import read_labels

    photo = small / "photo.png"
    refused(run("classify", photo, "-o", tmp_path / "l.jpg"), "lossy", "l.jpg")
    assert not any(tmp_path.iterdir())
    for name in ("l.png", "l.exr"):
        proc = run("classify", photo, "-o", tmp_path / name, "--themes", "3")
        assert proc.returncode == 0, proc.stderr[-2000:]
    labels = read_labels(tmp_path / "l.png")
    assert set(np.unique(labels)) == {1, 2, 3}
    np.testing.assert_array_equal(read_labels(tmp_path / "l.exr"), labels)


def test_unpack_to_a_full_disk_names_the_png(small, no_space):
    """The palette PNG writer's last flush (at close) failed outside its atomic write: the
    error named no file ('No space left on device')."""
    refused(run("unpack", small / "l.ttpack", no_space / "u.png"), f"{no_space}/u.png: ")
    assert {p.name for p in no_space.iterdir()} == {"old.exr", "filler"}


# -- work bounded by what the input can ask for -------------------------------------------

def test_a_render_larger_than_memory_is_refused_before_work(small, tmp_path):
    """A 300 KiB project of 4096-texel cells renders to 258048 x 258048: render held the
    whole image with no check, so it allocated until memory ran out (under a limit, the
    MemoryError line; without one, the kernel's OOM killer)."""
    idx = (np.arange(64 * 64).reshape(64, 64) % 3).astype(np.uint8)
    write_image(tmp_path / "i.png", idx)
    proc = run("new", tmp_path / "i.png", tmp_path / "h.ttproj", "--themes", "water,sand,grass",
               "--cell", "4096")
    assert proc.returncode == 0, proc.stderr[-2000:]
    limit = "import resource\nresource.setrlimit(resource.RLIMIT_AS, (2560 << 20, -1))"
    refused(run("render", tmp_path / "h.ttproj", tmp_path / "r.png", "--region",
                "0,0,20000,20000", prefix=limit), "20000 x 20000", "--region")
    assert not (tmp_path / "r.png").exists()


def test_a_perspective_frame_larger_than_memory_is_refused_before_work(small, tmp_path):
    """The CPU filters hold about 141 bytes per frame pixel: --size 16384x16384, which the
    size check allows, would hold 38 GB; it was tried until memory ran out."""
    limit = "import resource\nresource.setrlimit(resource.RLIMIT_AS, (2560 << 20, -1))"
    refused(run("perspective", small / "p.ttproj", tmp_path / "q.png", "--size", "4096x4096",
                "--no-cache", prefix=limit), "4096 x 4096", "--size")
    assert not any(tmp_path.iterdir())


def test_index_and_label_outputs_refuse_a_format_that_does_not_read_back(small, tmp_path):
    """OpenImageIO's RLA changes the last column of an image (about 50 of 360000 indices of a
    600^2 layer): unpack and classify wrote such files with exit 0."""
    refused(run("unpack", small / "l.ttpack", tmp_path / "u.rla"), "u.rla", "read back")
    refused(run("classify", small / "photo.png", "-o", tmp_path / "l.rla"), "l.rla",
            "class numbers")
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("suffix", [".bmp", ".tga", ".fits"])
def test_unpack_refuses_a_format_that_cannot_keep_16_bit_values(tmp_path, suffix):
    """OpenImageIO writes a uint16 layer's values to BMP and TGA scaled to 8 bits (60000 ->
    233) and to FITS halved into int16: unpack wrote them with exit 0."""
    index = np.full((8, 8), 1000, np.uint16)
    index[4:] = 60000
    write_image(tmp_path / "i.png", index)
    assert run("pack", tmp_path / "i.png", tmp_path / "i.ttpack").returncode == 0
    refused(run("unpack", tmp_path / "i.ttpack", tmp_path / f"u{suffix}"), "uint16")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["i.png", "i.ttpack"]


@pytest.mark.parametrize("name", ["r.null", "r.term"])
def test_an_output_openimageio_writes_to_no_file_is_refused(small, tmp_path, name):
    """'.null' and '.term' are OpenImageIO writers that make no file: render left a 0-byte
    image and exit 0 ('.term' drew the render on stdout with escape sequences)."""
    proc = run("render", small / "p.ttproj", tmp_path / name)
    refused(proc, "writes no file")
    assert proc.stdout == "" and not any(tmp_path.iterdir())


def test_unpack_refuses_a_depth_format_for_indices(small, tmp_path):
    """A .zfile holds depths as floats: unpack wrote the indices scaled to 0..1."""
    refused(run("unpack", small / "l.ttpack", tmp_path / "u.zfile"), "u.zfile", "read back")
    assert not any(tmp_path.iterdir())


def test_an_empty_file_named_for_the_null_reader_is_no_image(tmp_path):
    """OpenImageIO's null reader makes pixels from the name: an empty file called
    'x.null?RES=64x64&TYPE=uint8' was classified and packed as a 64 x 64 image."""
    fake = tmp_path / "x.null?RES=64x64&TYPE=uint8&VALUE=0.5"
    fake.write_bytes(b"")
    refused(run("pack", fake, tmp_path / "o.ttpack"), "not an image file")
    refused(run("classify", fake, "-o", tmp_path / "o.png"), "not an image file")
    assert [p.name for p in tmp_path.iterdir()] == [fake.name]


# -- outputs that failed only after the work ---------------------------------------------

def test_an_image_format_that_refuses_one_channel_is_refused_before_work(small, tmp_path):
    """GIF takes no one-channel image: classify --confidence c.gif classified the whole
    photo, then failed to write (and unpack u.gif read the layer first)."""
    proc = run("classify", small / "photo.png", "-o", tmp_path / "l.png", "--confidence",
               tmp_path / "c.gif")
    refused(proc, "c.gif", "1-channel")
    assert not proc.stderr.startswith("classify:")  # no stage ran
    refused(run("unpack", small / "l.ttpack", tmp_path / "u.gif"), "u.gif", "1-channel")
    assert not any(tmp_path.iterdir())


def test_the_cell_curve_chart_is_written_in_the_format_its_name_says(small, tmp_path):
    """convert --curve c.jpg wrote PNG bytes under the .jpg name."""
    refused(run("convert", small / "photo.png", tmp_path / "p.ttproj", "--curve",
                tmp_path / "c.jpg"), "c.jpg", ".svg")
    assert not any(tmp_path.iterdir())
    proc = run("convert", small / "photo.png", tmp_path / "p.ttproj", "--curve",
               tmp_path / "c.svg")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert b"<svg" in (tmp_path / "c.svg").read_bytes()[:2000]


def test_the_channel_probe_refuses_only_what_the_writer_says(tmp_path, monkeypatch):
    """The probe writes a 1 x 1 image in a temporary folder: one that cannot be made (a
    full /tmp) or where no image opens is no reason to refuse the output."""
    import tempfile

    from terratheme.core.errors import TerrathemeError
    from terratheme.core.io.image_format import check_writable_format

    check_writable_format(tmp_path / "c.png", channels=1)
    with pytest.raises(TerrathemeError, match="gif cannot hold this 1-channel image"):
        check_writable_format(tmp_path / "c.gif", channels=1)
    check_writable_format(tmp_path / "c.gif", channels=3)

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(tempfile, "TemporaryDirectory", full)
    check_writable_format(tmp_path / "c.gif", channels=1)
    monkeypatch.undo()
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.setattr(tempfile, "mkdtemp", lambda *a, **kw: str(gone / "missing"))
    check_writable_format(tmp_path / "c.gif", channels=1)  # no image opens there at all
    assert not any(tmp_path.glob("c.*"))
