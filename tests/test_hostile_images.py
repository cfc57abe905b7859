"""Hostile and awkward image files: exact pixels, one line naming the file, bounded work.

Regression tests for issue 16's image items (RGBA values changed on
reading, a 4th TIFF band taken for alpha, a stray ``libpng error`` line for
a 0 x 0 PNG, forged sizes, GeoTIFF tags of the wrong shape), the palette
PNGs ``classify`` writes, and fuzzing of small PNG, JPEG and TIFF files
through :class:`test_hostile_harness.BoundedReader`.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
import tifffile
from hostile_fuzz import (
    EDITS,
    campaign,
    patch_tiff_size,
    patch_tiff_tags,
    run_bytes,
    run_edited,
    run_truncations,
)
from hypothesis import strategies as st
from terratheme.core.classify.photo import prepare_photo
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.georef import (
    read_georeference,
    validate_georeference,
    write_georeferenced,
)
from terratheme.core.io.images import (
    MAX_COMPRESSION_RATIO,
    Bands,
    image_info,
    read_image,
    read_labels,
    read_region,
    write_image,
)
from test_hostile_harness import shared_reader


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png(width: int, height: int, colour_type: int, rows: bytes, extra: bytes = b"") -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + extra
            + _chunk(b"IDAT", zlib.compress(rows)) + _chunk(b"IEND", b""))


def test_a_0_by_0_png_is_one_line_and_no_libpng_noise(tmp_path, capfd):
    path = tmp_path / "empty.png"
    path.write_bytes(_png(0, 0, 0, b""))
    with pytest.raises(TerrathemeError, match=r"empty.png: image has no pixels \(0 x 0\)"):
        read_image(path)
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("cut", [10, 30, 60, 0.5, 0.9])
def test_damaged_pngs_print_nothing_but_our_one_line(tmp_path, capfd, cut):
    rng = np.random.default_rng(0)
    write_image(tmp_path / "a.png", rng.integers(0, 255, (32, 32, 3), dtype=np.uint8))
    data = (tmp_path / "a.png").read_bytes()
    n = int(len(data) * cut) if isinstance(cut, float) else cut
    (tmp_path / "cut.png").write_bytes(data[:n])
    with pytest.raises(CorruptFileError, match="cut.png") as exc:
        read_image(tmp_path / "cut.png")
    assert "\n" not in str(exc.value)
    assert "libpng" not in capfd.readouterr().err


@pytest.mark.parametrize("where", ["IHDR", "PLTE", "IDAT", "IEND"])
def test_a_damaged_chunk_is_refused_without_touching_stderr(tmp_path, capfd, monkeypatch,
                                                             where):
    # Issue 37: the reader sent the process's fd 2 to a file while libpng ran; a library
    # must not. The chunks are checked first instead, so libpng never sees the damage.
    import os

    redirected, dup2 = [], os.dup2

    def recording_dup2(fd, fd2, *args):
        redirected.append(fd2)
        return dup2(fd, fd2, *args)

    monkeypatch.setattr(os, "dup2", recording_dup2)
    write_image(tmp_path / "a.png", np.arange(64, dtype=np.uint8).reshape(8, 8, 1) % 3,
                palette=np.array([[0, 0, 0], [9, 9, 9], [200, 0, 0]], np.uint8))
    data = bytearray((tmp_path / "a.png").read_bytes())
    at = data.find(where.encode()) - 4
    data[at + 11 + struct.unpack_from(">I", data, at)[0]] ^= 0x10  # the chunk's CRC
    (tmp_path / "bad.png").write_bytes(bytes(data))
    with pytest.raises(CorruptFileError, match=f"bad.png: damaged PNG .CRC error in a b'{where}'"):
        read_image(tmp_path / "bad.png")
    assert redirected == []
    monkeypatch.undo()
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize(("suffix", "dtype"), [(".png", np.uint8), (".png", np.uint16),
                                               (".tif", np.uint8), (".tif", np.uint16)])
def test_rgba_values_survive_a_round_trip(tmp_path, suffix, dtype):
    # Six colours at eight alphas: OpenImageIO used to premultiply them on reading.
    top = np.iinfo(dtype).max
    colours = np.array([[200, 100, 50], [0, 255, 0], [10, 20, 30], [255, 255, 255],
                        [1, 2, 3], [90, 0, 200]]) * (top // 255)
    rgba = np.zeros((6, 8, 4), dtype)
    rgba[:, :, :3] = colours[:, None, :]
    rgba[:, :, 3] = np.linspace(0, top, 8).astype(dtype)[None, :]
    write_image(tmp_path / f"a{suffix}", rgba)
    np.testing.assert_array_equal(read_image(tmp_path / f"a{suffix}"), rgba)


def test_an_rgba_png_from_another_writer_reads_unchanged(tmp_path):
    image = pytest.importorskip("PIL.Image")
    rng = np.random.default_rng(1)
    rgba = rng.integers(0, 256, (8, 8, 4), dtype=np.uint8)
    image.fromarray(rgba, "RGBA").save(tmp_path / "pil.png")
    np.testing.assert_array_equal(read_image(tmp_path / "pil.png"), rgba)


def _nir_tiff(path, extrasample: int) -> np.ndarray:
    data = np.zeros((4, 6, 4), np.uint8)
    data[..., :3] = (40, 90, 200)
    data[:, :3, 3] = 0    # water is dark in the near infrared
    data[:, 3:, 3] = 180
    tifffile.imwrite(path, data, photometric="rgb", extrasamples=[extrasample])
    return data


def test_a_fourth_band_that_is_not_alpha_is_not_taken_for_alpha(tmp_path):
    data = _nir_tiff(tmp_path / "nir.tif", 0)
    assert image_info(tmp_path / "nir.tif").alpha_channel == -1
    np.testing.assert_array_equal(read_image(tmp_path / "nir.tif"), data)
    photo = read_image(tmp_path / "nir.tif", bands=Bands.PHOTO)
    np.testing.assert_array_equal(photo, data[..., :3])
    _, valid = prepare_photo(photo)
    assert valid is None  # no "no data" pixels, so no extra theme
    np.testing.assert_array_equal(read_region(tmp_path / "nir.tif", 1, 1, 3, 2,
                                              bands=Bands.PHOTO), data[1:3, 1:4, :3])


def test_a_marked_alpha_band_is_kept(tmp_path):
    data = _nir_tiff(tmp_path / "alpha.tif", 2)
    photo = read_image(tmp_path / "alpha.tif", bands=Bands.PHOTO)
    np.testing.assert_array_equal(photo, data)
    _, valid = prepare_photo(photo)
    assert valid is not None and not valid[:, :3].any() and valid[:, 3:].all()


def test_grey_plus_alpha_and_five_bands(tmp_path):
    grey_alpha = np.zeros((3, 3, 2), np.uint8)
    grey_alpha[..., 0], grey_alpha[..., 1] = 77, 255
    write_image(tmp_path / "ga.png", grey_alpha)
    np.testing.assert_array_equal(read_image(tmp_path / "ga.png", bands=Bands.PHOTO), grey_alpha)
    five = np.arange(3 * 3 * 5, dtype=np.uint8).reshape(3, 3, 5)
    tifffile.imwrite(tmp_path / "five.tif", five, photometric="rgb", planarconfig="contig",
                     extrasamples=[0, 2])
    np.testing.assert_array_equal(read_image(tmp_path / "five.tif", bands=Bands.PHOTO),
                                  five[..., [0, 1, 2, 4]])


def test_a_forged_png_size_is_refused_at_once(tmp_path):
    path = tmp_path / "big.png"
    path.write_bytes(_png(60000, 60000, 2, b"\0" * 13 * 4))
    with pytest.raises(CorruptFileError, match="big.png"):
        read_image(path)


def test_a_tiff_declaring_more_pixels_than_its_bytes_can_hold_is_refused(tmp_path):
    path = tmp_path / "forged.tif"
    tifffile.imwrite(path, np.zeros((2, 2), np.uint8))
    patch_tiff_size(path, 30000, 30000)
    with pytest.raises(CorruptFileError, match=r"forged.tif: header declares 30000 x 30000 x 1 "
                                               r"pixels \(858 MiB\) from a \d+-byte file"):
        read_image(path)


def test_a_tiff_declaring_a_tile_larger_than_its_bytes_can_hold_is_refused(tmp_path):
    # A 32 x 32 image whose one tile would be decoded whole: 3 GiB from a tiny file.
    path = tmp_path / "tile.tif"
    tifffile.imwrite(path, np.zeros((32, 32, 3), np.uint8), tile=(16, 16), compression="zlib")
    patch_tiff_tags(path, {322: 32768, 323: 32768})
    for read in (read_image, lambda p: read_region(p, 0, 0, 8, 8)):
        with pytest.raises(CorruptFileError, match=r"tile.tif: header declares 32768 x 32768 x 3"):
            read(path)


def test_a_truncated_jpeg_read_by_window_is_refused(tmp_path):
    # libjpeg fills the rows it lacks with grey and sets an error: a window must not take them.
    path = tmp_path / "photo.jpg"
    write_image(path, np.random.default_rng(0).integers(0, 255, (256, 256, 3), np.uint8))
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(CorruptFileError, match="photo.jpg: damaged or truncated image"):
        read_region(path, 0, 200, 64, 56)


def test_palette_pngs_hold_class_numbers_and_show_colours(tmp_path):
    pil = pytest.importorskip("PIL.Image")
    labels = np.array([[0, 1, 2], [2, 1, 0]], np.uint8)
    palette = np.array([[0, 0, 0], [225, 200, 140], [40, 90, 200]], np.uint8)
    write_image(tmp_path / "l.png", labels, palette=palette)
    # An independent decoder sees a palette image with our indices and colours.
    with pil.open(tmp_path / "l.png") as im:
        assert im.mode == "P"
        np.testing.assert_array_equal(np.asarray(im), labels)
        assert np.array(im.getpalette()[:9]).reshape(3, 3).tolist() == palette.tolist()
    np.testing.assert_array_equal(read_labels(tmp_path / "l.png"), labels)
    np.testing.assert_array_equal(read_image(tmp_path / "l.png"), palette[labels])
    with pytest.raises(TerrathemeError, match="value 2 has no colour in a palette of 2"):
        write_image(tmp_path / "m.png", labels, palette=palette[:2])
    with pytest.raises(TerrathemeError, match="single-channel 8-bit PNG"):
        write_image(tmp_path / "m.tif", labels, palette=palette)
    assert not (tmp_path / "m.png").exists() and not (tmp_path / "m.tif").exists()


def test_foreign_palette_pngs_and_ambiguous_palettes(tmp_path):
    pil = pytest.importorskip("PIL.Image")
    labels = np.array([[0, 3, 1, 3]], np.uint8)
    im = pil.fromarray(labels, "P")
    im.putpalette([0, 0, 0, 10, 10, 10, 20, 20, 20, 30, 30, 30])
    im.save(tmp_path / "p.png", bits=2)
    np.testing.assert_array_equal(read_labels(tmp_path / "p.png"), labels)
    im.putpalette([0, 0, 0, 10, 10, 10, 20, 20, 20, 10, 10, 10])  # 1 and 3 look alike
    im.save(tmp_path / "dup.png")
    with pytest.raises(TerrathemeError, match="dup.png: palette entries share a colour"):
        read_labels(tmp_path / "dup.png")


def test_labels_from_grey_and_equal_channel_images(tmp_path):
    labels = np.array([[0, 5], [7, 255]], np.uint8)
    write_image(tmp_path / "g.png", labels)
    np.testing.assert_array_equal(read_labels(tmp_path / "g.png"), labels)
    write_image(tmp_path / "rgb.png", np.repeat(labels[..., None], 3, axis=2))
    np.testing.assert_array_equal(read_labels(tmp_path / "rgb.png"), labels)
    colour = np.zeros((2, 2, 3), np.uint8)
    colour[0, 0, 1] = 9
    write_image(tmp_path / "c.png", colour)
    with pytest.raises(TerrathemeError, match="c.png: a label image must hold single-channel"):
        read_labels(tmp_path / "c.png")


GEO = {"ModelPixelScale": [2.0, 2.0, 0.0], "ModelTiepoint": [0, 0, 0, 500.0, 900.0, 0],
       "GeoKeyDirectory": [1, 1, 0, 1, 1024, 0, 1, 1], "GeoAsciiParams": "WGS 84|"}


@pytest.mark.parametrize(("tag", "value", "match"), [
    ("ModelTiepoint", [0.0, 0.0, 0.0, 1.0, 2.0], "ModelTiepoint has 5 numbers"),
    ("ModelPixelScale", [1.0], "ModelPixelScale has 1 numbers"),
    ("ModelTransformation", [1.0] * 15, "ModelTransformation has 15 numbers"),
    ("GeoKeyDirectory", [1, 1, 0, 70000], "GeoKeyDirectory holds a value"),
])
def test_geotiff_tags_of_the_wrong_shape_are_refused(tmp_path, tag, value, match):
    path = tmp_path / "geo.tif"
    write_image(path, np.zeros((4, 4, 3), np.uint8))
    tifffile_tag = {"ModelTiepoint": 33922, "ModelPixelScale": 33550,
                    "ModelTransformation": 34264, "GeoKeyDirectory": 34735}[tag]
    kind = "H" if tag == "GeoKeyDirectory" else "d"
    raw = [v & 0xFFFF for v in value] if kind == "H" else value
    if tag == "GeoKeyDirectory":
        with pytest.raises(TerrathemeError, match=match):
            validate_georeference({tag: value})
        return
    tifffile.imwrite(path, np.zeros((4, 4, 3), np.uint8),
                     extratags=[(tifffile_tag, kind, len(raw), raw, False)])
    with pytest.raises(CorruptFileError, match=f"geo.tif: georeference {match}"):
        read_georeference(path)


def test_a_georeference_round_trip(tmp_path):
    write_georeferenced(tmp_path / "g.tif", np.zeros((4, 4, 3), np.uint8), GEO)
    geo = read_georeference(tmp_path / "g.tif")
    assert {k: geo[k] for k in GEO} == {**GEO, "ModelTiepoint": [0.0, 0.0, 0.0, 500.0, 900.0,
                                                                   0.0]}
    with pytest.raises(TerrathemeError, match="GeoAsciiParams is not Latin-1"):
        validate_georeference({"GeoAsciiParams": "\u4e16"})
    with pytest.raises(TerrathemeError, match="georeference must be an object"):
        validate_georeference([1])


# -- fuzzing within the time and memory bound ---------------------------------

@pytest.fixture(scope="module")
def bounded():
    return shared_reader()


@pytest.fixture(scope="module")
def samples(tmp_path_factory) -> dict[str, bytes]:
    d = tmp_path_factory.mktemp("img")
    rng = np.random.default_rng(2)
    img = rng.integers(0, 255, (8, 8, 3), dtype=np.uint8)
    write_image(d / "a.png", img)
    write_image(d / "a.jpg", img)
    write_georeferenced(d / "a.tif", img, GEO)
    rgba = np.dstack([img, rng.integers(0, 255, (8, 8), dtype=np.uint8)])
    write_image(d / "rgba.png", rgba)
    write_image(d / "l.png", (img[..., 0] % 3).astype(np.uint8),
                palette=np.array([[0, 0, 0], [9, 9, 9], [200, 0, 0]], np.uint8))
    return {p.name: p.read_bytes() for p in d.iterdir()}


CASES = [("a.png", "image"), ("a.jpg", "image"), ("a.tif", "georef"), ("a.tif", "image"),
         ("rgba.png", "photo"), ("l.png", "labels")]


def _suffix(name: str) -> str:
    return name[name.index("."):]


@campaign
@pytest.mark.parametrize(("name", "reader"), CASES)
def test_truncations_of_small_images(budget, bounded, samples, tmp_path, name, reader):
    path = tmp_path / f"cut{_suffix(name)}"
    run_truncations(bounded, reader, samples[name], path, budget)
    assert run_bytes(bounded, reader, path, samples[name]).kind == "ok"


@campaign
def test_flips_and_insertions(budget, bounded, samples, tmp_path):
    budget.explore(lambda case, edits: run_edited(
        bounded, case[1], samples[case[0]], tmp_path / f"mut{_suffix(case[0])}", edits),
        case=st.sampled_from(CASES), edits=EDITS)


SIZES = st.sampled_from([0, 1, 2, 255, 65535, 1 << 20, 1 << 24, 0x7FFFFFFF, 0xFFFFFFFF])


@campaign
def test_hostile_png_header_sizes(budget, bounded, tmp_path):
    budget.explore(lambda width, height, colour_type: run_bytes(
        bounded, "image", tmp_path / "h.png", _png(width, height, colour_type, b"\0" * 64)),
        width=SIZES, height=SIZES, colour_type=st.sampled_from([0, 2, 3, 4, 6, 7]))


def _forged_tiff(path, width, height) -> bytes:
    tifffile.imwrite(path, np.zeros((2, 2), np.uint8))
    patch_tiff_size(path, width, height)
    return path.read_bytes()


@campaign
def test_hostile_tiff_header_sizes(budget, bounded, tmp_path):
    path = tmp_path / "h.tif"
    budget.explore(lambda width, height: run_bytes(bounded, "image", path,
                                                   _forged_tiff(path, width, height)),
                   width=SIZES, height=SIZES)


def test_pack_and_unpack_keep_every_texel_of_an_rgba_index_image(tmp_path, capsys):
    from terratheme.app.cli import main

    # Issue 16: 32 of these 64 texels changed (alpha was premultiplied on reading).
    colours = np.array([[200, 100, 50, 255], [0, 255, 0, 128], [10, 20, 30, 0],
                        [255, 255, 255, 64], [1, 2, 3, 200], [90, 0, 200, 17]], np.uint8)
    image = colours[np.random.default_rng(0).integers(0, 6, (8, 8))]
    write_image(tmp_path / "idx.png", image)
    assert main(["pack", str(tmp_path / "idx.png"), str(tmp_path / "idx.ttpack")]) == 0
    assert main(["unpack", str(tmp_path / "idx.ttpack"), str(tmp_path / "back.png")]) == 0
    np.testing.assert_array_equal(read_image(tmp_path / "back.png"), image)


def test_a_png_is_checked_once_per_version(tmp_path, monkeypatch):
    # A tiled conversion opens the photo once per tile: its chunks are read once.
    from terratheme.core.io import png

    write_image(tmp_path / "a.png", np.zeros((8, 8, 3), np.uint8))
    png.check_png_chunks(tmp_path / "a.png")
    calls = []
    monkeypatch.setattr(png, "open", lambda *a: calls.append(a) or open(*a), raising=False)
    png.check_png_chunks(tmp_path / "a.png")
    assert calls == []
    data = (tmp_path / "a.png").read_bytes()
    (tmp_path / "a.png").write_bytes(data[:-6])  # another version: checked again
    with pytest.raises(CorruptFileError, match="truncated PNG"):
        png.check_png_chunks(tmp_path / "a.png")
    assert calls


def test_a_flat_one_channel_png_as_large_as_deflate_allows_is_read(tmp_path):
    # 6000^2 grey zeros: ~35 KB of PNG for 36 MB of pixels (1 byte a pixel, not 3).
    path = tmp_path / "flat.png"
    write_image(path, np.zeros((6000, 6000), np.uint8))
    assert path.stat().st_size * MAX_COMPRESSION_RATIO + (4 << 20) < 3 * 6000 * 6000
    assert read_image(path).shape[:2] == (6000, 6000)
