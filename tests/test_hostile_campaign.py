"""What the whole-CLI hostile-input campaign of h9 found, one regression test per item.

The campaign ran every subcommand on hostile files (photos of every kind,
masks, legends, engine maps, projects with a damaged colour map or render
style, theme folders) and hostile option values, through the real command
line. Each item here failed the project's rule before its fix: a traceback,
a second stderr line, a message that did not name the file, or an error
found only after the long work (or after a first output was written).
Everything runs in-process on tiny files; the seeded mutation runs of engine
maps have a quick and a ``-m slow`` budget (:data:`hostile_fuzz.campaign`).
"""

from __future__ import annotations

import io
import json
import random
import zipfile

import numpy as np
import pytest
import tifffile
from hostile_fuzz import campaign, hidden_files, patch_tiff_size
from terratheme.app.cli import main
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.exchange.maps_to_grid import grid_from_maps
from terratheme.core.exchange.terrain3d import write_control_map
from terratheme.core.io.archive import parse_json
from terratheme.core.io.images import read_image, read_region, write_image
from terratheme.core.io.legend import parse_legend
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, load_project, save_project
from terratheme.core.packing import pack
from terratheme.core.themes.library import read_theme_library, shipped_theme_library


def _refused(capfd, argv: list[str], *needles: str) -> str:
    """``terratheme ARGV`` exits 2 with one stderr line holding every needle; the line."""
    assert main([str(a) for a in argv]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def _photo() -> np.ndarray:
    img = np.zeros((32, 32, 3), np.uint8)
    img[:, 16:] = (200, 180, 120)
    img[:, :16] = (40, 90, 200)
    return img


@pytest.fixture()
def files(tmp_path):
    """A photo, a scribble mask, a half-size mask, a small project and a packed layer."""
    write_image(tmp_path / "photo.png", _photo())
    mask = np.zeros((32, 32), np.uint8)
    mask[8, 2:14], mask[20, 18:30] = 1, 2
    write_image(tmp_path / "mask.png", mask)
    write_image(tmp_path / "half.png", mask[:16])
    library = shipped_theme_library().select(["water", "sand"])
    save_project(tmp_path / "p.ttproj", ThematicTexture(
        IndexGrid(np.eye(5, dtype=np.uint8), (4, 4)), library, {}))
    return tmp_path


def _outputs(folder) -> list[str]:
    keep = {"photo.png", "mask.png", "half.png", "p.ttproj", "p.ttpack"}
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


# -- outputs and option values checked before any work ------------------------

@pytest.mark.parametrize("argv", [
    ["render", "{d}/p.ttproj", "{d}/out.xyz"],
    ["unpack", "{d}/p.ttpack", "{d}/out.xyz"],
    ["classify", "{d}/photo.png", "-o", "{d}/l.xyz"],
    # found: the labels were written, then the confidence failed (a half-written set)
    ["classify", "{d}/photo.png", "-o", "{d}/l.png", "--confidence", "{d}/c.xyz"],
    # found: after the whole conversion, a message naming the temporary file
    ["convert", "{d}/photo.png", "{d}/o.ttproj", "--preview", "{d}/pv.xyz"],
    ["perspective", "{d}/photo.png", "{d}/out", "--no-cache"],
])
def test_an_image_output_no_writer_takes_is_refused_before_work(files, capfd, argv):
    pack(np.eye(5, dtype=np.uint8)).save(files / "p.ttpack")
    args = [a.format(d=files) for a in argv]
    line = _refused(capfd, args, "name the image .png, .tif")
    assert ("no image format is written as '.xyz'" in line) or ("has no extension" in line)
    assert _outputs(files) == [] and not hidden_files(files)


@pytest.mark.parametrize(("size", "needle"), [
    ("0x0", "frame size 0x0 must be within 1..16384"),  # found: ZeroDivisionError traceback
    ("0x5", "frame size 0x5"),
    ("99999x10", "frame size 99999x10"),  # found: "not enough memory" after the warm-up
])
def test_a_perspective_frame_size_out_of_range_is_refused(files, capfd, size, needle):
    _refused(capfd, ["perspective", files / "photo.png", files / "o.png", "--no-cache",
                     "--size", size], needle)
    assert _outputs(files) == []


@pytest.mark.parametrize(("argv", "needle"), [
    (["--size", "0x0"], "--size 0x0: each side must be 200..8192 pixels"),
    # found: 865 lines of "QPainter::setPen: Painter not active" before our line
    (["--size", "99999x99999"], "--size 99999x99999: each side must be"),
    (["--screenshot", "{d}"], "is a folder, not an output file"),
    (["--screenshot", "{d}/photo.png/s.png"], "cannot make the folder"),
])
def test_app_options_are_checked_before_qt_starts(files, capfd, argv, needle):
    args = [a.format(d=files) for a in argv]
    _refused(capfd, ["app", files / "p.ttproj", *args], needle)


@pytest.mark.parametrize(("argv", "needle"), [
    (["--ignore", "-1"], "a mask class value is a whole number 0..255, not '-1'"),
    (["--ignore", "999"], "not '999'"),
])
def test_classify_ignore_values_outside_0_255_are_refused(files, capfd, argv, needle):
    with pytest.raises(SystemExit) as exc:
        main(["classify", str(files / "photo.png"), "-o", str(files / "l.png"),
              "--scribbles", str(files / "mask.png"), *argv])
    assert exc.value.code == 2 and needle in capfd.readouterr().err


@pytest.mark.parametrize("argv", [
    ["classify", "{d}/photo.png", "-o", "{d}/l.png", "--scribbles", "{d}/half.png"],
    ["classify", "{d}/photo.png", "-o", "{d}/l.png", "--train", "{d}/photo.png",
     "{d}/half.png"],
    ["convert", "{d}/photo.png", "{d}/o.ttproj", "--scribbles", "{d}/half.png"],
])
def test_a_mask_of_the_wrong_size_names_both_files_before_work(files, capfd, argv):
    _refused(capfd, [a.format(d=files) for a in argv],
             f"{files}/half.png: the ", "mask is 32 x 16 pixels but its photo "
             f"{files}/photo.png is 32 x 32")
    assert _outputs(files) == []


def test_convert_refuses_a_class_named_twice(files, capfd):
    # found: "1=sand,1=water" silently named class 1 water
    _refused(capfd, ["convert", files / "photo.png", files / "o.ttproj", "--scribbles",
                     files / "mask.png", "--themes", "1=sand,1=water"],
             "--themes '1=sand,1=water': class 1 is named twice")


@pytest.mark.parametrize(("argv", "needle"), [
    (["--themes", ","], "--themes ',' names no theme"),  # found: "library has only 0 themes"
    (["--themes", "water,sand", "--from", "splatmap", "--step", "0"],
     "--step must be a whole number of at least 1"),
])
def test_new_option_values(files, capfd, argv, needle):
    write_image(files / "i.png", np.eye(5, dtype=np.uint8))
    try:
        _refused(capfd, ["new", files / "i.png", files / "o.ttproj", *argv], needle)
    except SystemExit as exc:  # an argparse type: usage, then the line
        assert exc.code == 2 and needle in capfd.readouterr().err
    assert not (files / "o.ttproj").exists()


# -- messages that name the file ---------------------------------------------------

@pytest.mark.parametrize(("image", "needle"), [
    (np.full((5, 5), 7, np.uint8), "index grid uses theme index 7"),
    (np.zeros((1, 1), np.uint8), "index grid needs at least 2 x 2 vertices"),
    (np.full((5, 5), 1.5, np.float32), "index grid must hold integers"),
    # found: whole floats past int64 wrapped in a cast (a warning, then a wrong index)
    (np.full((5, 5), 1e30, np.float32), "index grid has index 1000000015047466219876688855040"),
    (np.full((5, 5), -1e30, np.float32), "index grid has a negative index (-1000000015047"),
])
def test_new_index_image_errors_name_the_image(files, capfd, image, needle):
    suffix = ".tif" if image.dtype == np.float32 else ".png"
    write_image(files / f"i{suffix}", image)
    _refused(capfd, ["new", files / f"i{suffix}", files / "o.ttproj", "--themes", "water,sand"],
             f"i{suffix}: {needle}")


@pytest.mark.parametrize(("image", "needle"), [
    (np.zeros((8, 8, 3), np.float32), "pixel type float32 cannot be packed"),
    (np.random.default_rng(0).integers(0, 255, (20, 20, 3), np.uint8), "more than the 256"),
])
def test_pack_errors_name_the_image(files, capfd, image, needle):
    suffix = ".tif" if image.dtype == np.float32 else ".png"
    write_image(files / f"i{suffix}", image)
    _refused(capfd, ["pack", files / f"i{suffix}", files / "o.ttpack"], f"i{suffix}: ")
    assert not (files / "o.ttpack").exists()


def test_a_grey_weight_map_must_be_grey(files, capfd):
    # found: an RGB photo was taken as a weight map (its red channel)
    _refused(capfd, ["new", files / "photo.png", files / "photo.png", files / "o.ttproj",
                     "--themes", "water,sand", "--from", "weights"],
             "photo.png: a weight map is a grey image")


def _rezip(src, **members: bytes | None) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for info in zin.infolist():
            data = members.get(info.filename.replace(".", "_"), zin.read(info.filename))
            z.writestr(info.filename, data)
    return buf.getvalue()


@pytest.fixture(scope="module")
def coloured(tmp_path_factory):
    """A converted 32 x 32 photo: a project with an AVIF colour map and a shaped style."""
    folder = tmp_path_factory.mktemp("coloured")
    write_image(folder / "photo.png", _photo())
    assert main(["convert", str(folder / "photo.png"), str(folder / "c.ttproj"), "--cell", "8",
                 "--colour-map", "0.5"]) == 0
    with zipfile.ZipFile(folder / "c.ttproj") as zf:
        assert "colour_map.avif" in zf.namelist()
    return folder / "c.ttproj"


@pytest.mark.parametrize("avif", [b"", b"\x00\x00\x00\x10ftypavif" + bytes(40),
                                  b"not an image at all"])
def test_a_damaged_colour_map_names_the_project_and_member(coloured, tmp_path, avif):
    (tmp_path / "bad.ttproj").write_bytes(_rezip(coloured, colour_map_avif=avif))
    with pytest.raises(CorruptFileError, match=r"bad.ttproj: colour_map.avif: ") as exc:
        load_project(tmp_path / "bad.ttproj")
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize(("render", "needle"), [
    ({"boundary": {"width": -3.0}}, "boundary width must be in 0..4096"),
    ({"boundary": {"seed": -1}}, "boundary seed must be in 0"),
    ({"boundary": {"zzz": 1}}, "bad boundary options"),
    ({"blend": "histogram"}, "project render style must be"),
])
@pytest.mark.parametrize("command", ["info", "render", "export", "perspective", "app"])
def test_a_bad_render_style_names_the_project(coloured, tmp_path, capfd, render, needle,
                                              command):
    with zipfile.ZipFile(coloured) as zf:
        manifest = json.loads(zf.read("manifest.json"))
    manifest["metadata"]["render"] = render
    path = tmp_path / "style.ttproj"
    path.write_bytes(_rezip(coloured, manifest_json=json.dumps(manifest).encode()))
    tail = {"info": [], "render": [tmp_path / "o.png"],
            "export": [tmp_path / "out", "--engine", "geotiff"],
            "perspective": [tmp_path / "o.png", "--no-cache"],
            "app": ["--screenshot", tmp_path / "o.png"]}[command]
    _refused(capfd, [command, path, *tail], "style.ttproj: ", needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["style.ttproj"]


# -- the readers' own gaps ----------------------------------------------------------------

def test_every_exr_header_byte_set_to_ff_is_read_or_one_line(tmp_path):
    # found: a damaged attribute name made OpenImageIO's error text non-UTF-8, and reading
    # its error raised UnicodeDecodeError (a traceback from classify, new --from terrain3d)
    write_image(tmp_path / "a.exr", _photo().astype(np.float32) / 255)
    data = (tmp_path / "a.exr").read_bytes()
    for pos in range(8, 340):
        path = tmp_path / "h.exr"
        path.write_bytes(data[:pos] + b"\xff" + data[pos + 1:])
        try:
            read_image(path)
        except TerrathemeError as exc:
            assert "h.exr" in str(exc) and "\n" not in str(exc)


def _tall_tiff(path, rows: int) -> None:
    """A 2 x 2 RGB TIFF (one strip of 2 rows) whose header then claims 1 x ``rows`` pixels."""
    tifffile.imwrite(path, np.full((2, 2, 3), 77, np.uint8), photometric="rgb")
    patch_tiff_size(path, 1, rows)


@pytest.mark.parametrize("rows", [3, 1000, 65535])
def test_a_tiff_listing_fewer_strips_than_its_rows_is_refused(tmp_path, capfd, rows):
    # found: read as zeros and stray file bytes (convert, classify, pack, perspective: exit 0),
    # while the tiled path said "damaged scanlines"
    _tall_tiff(tmp_path / "tall.tif", rows)
    with pytest.raises(CorruptFileError, match=rf"tall.tif: TIFF header declares 1 x {rows} "
                                               r"pixels in [\d,]+ strips but lists 1"):
        read_image(tmp_path / "tall.tif")
    with pytest.raises(CorruptFileError, match="tall.tif: TIFF header declares"):
        read_region(tmp_path / "tall.tif", 0, 0, 1, 1)
    assert capfd.readouterr().err == ""  # tifffile's warnings are not shown


def test_a_truncated_splatmap_prints_one_line_only(files, capfd):
    # found: "libpng error: IDAT: ..." on stderr before our line (a reader of its own)
    write_image(files / "s.png", np.random.default_rng(0).integers(0, 255, (32, 32, 4),
                                                                   dtype=np.uint8))
    data = (files / "s.png").read_bytes()
    (files / "s.png").write_bytes(data[:len(data) // 2])
    _refused(capfd, ["new", files / "s.png", files / "o.ttproj", "--themes", "water,sand",
                     "--from", "splatmap"], "s.png: truncated PNG")


@pytest.mark.parametrize("text", ['{"1": "a", "1": "b"}', '{"classes": {"2": "x", "2": "y"}}'])
def test_a_legend_naming_a_class_twice_in_json_is_refused(text):
    # found: JSON kept the last name silently (the CSV form was already refused)
    with pytest.raises(CorruptFileError, match="leg.json is not valid JSON .the key '.' "
                                               "appears twice"):
        parse_legend(text.encode(), "leg.json")


def test_a_legend_with_a_byte_order_mark_reads():
    # found: "the legend names no class" (the first line was taken for a header)
    assert parse_legend("\ufeff1,water\n2,sand\n".encode(), "l.csv") == {1: "water", 2: "sand"}
    assert parse_legend('\ufeff{"1": "water"}'.encode(), "l.json") == {1: "water"}


def test_duplicate_keys_are_refused_in_every_json_reader():
    with pytest.raises(CorruptFileError, match="m.json is not valid JSON .the key 'cell'"):
        parse_json(b'{"cell": [16, 16], "cell": [1, 1]}', "m.json")
    assert parse_json(b'{"a": {"b": 1}, "b": {"b": 2}}', "x") == {"a": {"b": 1}, "b": {"b": 2}}


TEX = np.full((8, 8, 3), 90, np.uint8)
GOOD = {"name": "a", "colour": [1, 2, 3], "file": "a.png"}


@pytest.mark.parametrize(("meta", "error", "match"), [
    (b"\xff\xfe{", CorruptFileError, "is not valid JSON"),  # found: UnicodeDecodeError
    ("[" * 100_000, CorruptFileError, "nests deeper than 32"),  # found: RecursionError
    ({"themes": 5}, CorruptFileError, "not a valid theme list"),  # found: TypeError
    ({"themes": []}, CorruptFileError, "not a valid theme list"),
    ({"themes": [dict(GOOD, file=5)]}, CorruptFileError, "file must be a file name"),
    ({"themes": [dict(GOOD, file="/etc/passwd")]}, CorruptFileError, "not '/etc/passwd'"),
    ({"themes": [dict(GOOD, file="../x/a.png")]}, CorruptFileError, "not '../x/a.png'"),
    ({"themes": [dict(GOOD, name="a\nb")]}, CorruptFileError, "name must be one printable"),
    ({"themes": [dict(GOOD, name="a" * 65)]}, CorruptFileError, "of 1..64 characters"),
    ({"themes": [dict(GOOD, colour=[1.5, 2, 3])]}, CorruptFileError, "colour must be three"),
    ({"themes": [dict(GOOD, colour=[1, 2, 999])]}, CorruptFileError, "theme 0: colour"),
    ({"themes": [GOOD, GOOD]}, CorruptFileError, "theme 1: a theme called 'a' is already"),
    ({"themes": [dict(GOOD, file="zz.png")]}, CorruptFileError, "theme 0: .*zz.png: no such"),
    ({"version": 9, "themes": [GOOD]}, UnsupportedVersionError, "theme list version 9"),
    ('{"themes": [], "themes": []}', CorruptFileError, "the key 'themes' appears twice"),
])
def test_a_hostile_theme_folder_is_one_line_naming_themes_json(tmp_path, meta, error, match):
    write_image(tmp_path / "a.png", TEX)
    text = meta if isinstance(meta, bytes | str) else json.dumps(meta)
    (tmp_path / "themes.json").write_bytes(text.encode() if isinstance(text, str) else text)
    with pytest.raises(error, match=match) as exc:
        read_theme_library(tmp_path)
    assert str(exc.value).startswith(str(tmp_path / "themes.json")) and "\n" not in str(
        exc.value)


def test_an_oversized_theme_list_is_refused_unread(tmp_path):
    (tmp_path / "themes.json").write_text(json.dumps({"themes": [], "pad": "x" * (1 << 20)}))
    with pytest.raises(CorruptFileError, match="larger than 1048576 bytes"):
        read_theme_library(tmp_path)


def test_the_shipped_theme_folder_still_reads():
    assert len(shipped_theme_library()) >= 9


# -- seeded mutations of engine maps ------------------------------------------------

def _mutants(data: bytes, rng: random.Random, count: int, header: int):
    """Truncations, flips (half of them in the header), header words set to 0 / max."""
    for k in range(count):
        yield data[:rng.randrange(len(data))]
        out = bytearray(data)
        for _ in range(1 + k % 3):
            out[rng.randrange(min(header, len(out)) if k % 2 else len(out))] ^= rng.randrange(
                1, 256)
        yield bytes(out)
        out = bytearray(data)
        at = rng.randrange(min(header, len(out) - 4))
        out[at:at + 4] = (b"\0\0\0\0", b"\xff\xff\xff\xff", b"\xff\xff\xff\x7f")[k % 3]
        yield bytes(out)


@campaign
@pytest.mark.parametrize("kind", ["splatmap", "control"])
def test_mutated_engine_maps_read_or_are_one_line(budget, tmp_path, capfd, kind):
    rng = random.Random(f"h9-{kind}")
    if kind == "splatmap":
        path, read = tmp_path / "s.png", lambda p: grid_from_maps([str(p)], "splatmap", 4, 1)
        write_image(path, np.random.default_rng(1).integers(0, 255, (16, 16, 4), np.uint8))
    else:
        path, read = tmp_path / "c.exr", lambda p: grid_from_maps([str(p)], "terrain3d", 32, 1)
        write_control_map(path, np.arange(81, dtype=np.uint32).reshape(9, 9) << 10)
    data = path.read_bytes()
    for mutant in _mutants(data, rng, budget.examples * 2, header=320):
        path.write_bytes(mutant)
        try:
            read(path)
        except TerrathemeError as exc:
            assert path.name in str(exc) and "\n" not in str(exc), exc
    assert "libpng" not in capfd.readouterr().err
