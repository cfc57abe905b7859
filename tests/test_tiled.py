"""Tiled reading and writing (bounded memory), tile jobs, GeoTIFF georeference round trip."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.georef import (
    read_georeference,
    scale_georeference,
    world_file_lines,
    write_georeference,
    write_georeferenced,
)
from terratheme.core.io.images import image_info, read_image, read_region, write_image
from terratheme.core.io.tiled_writer import TiledImageWriter
from terratheme.core.io.tiles import run_tiles, tile_windows

GEOREF = {
    "ModelPixelScale": [0.5, 0.5, 0.0],
    "ModelTiepoint": [0.0, 0.0, 0.0, 1000.0, 2000.0, 0.0],
    "GeoKeyDirectory": [1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32640],
    "GeoAsciiParams": "WGS 84 / UTM zone 40N|",
    "GDAL_NODATA": "0",
}


def _ramp(h, w, c, dtype):
    rng = np.random.default_rng(h * 31 + w)
    info = np.iinfo(dtype) if np.dtype(dtype).kind in "iu" else None
    if info is None:
        return rng.random((h, w, c)).astype(dtype)
    return rng.integers(0, int(info.max) + 1, (h, w, c), dtype=dtype)


@pytest.mark.parametrize(
    ("name", "dtype", "kw"),
    [
        ("big.tif", np.uint8, {"tile": 64, "bigtiff": True}),
        ("deep.tif", np.uint16, {"tile": 32}),
        ("hdr.exr", np.float32, {"tile": 32, "compression": "zip"}),
    ],
)
def test_tiled_writer_and_windows_read_back_exactly(tmp_path, name, dtype, kw):
    img = _ramp(150, 203, 3, dtype)
    path = tmp_path / name
    with TiledImageWriter(path, 203, 150, 3, dtype, **kw) as out:
        for win in tile_windows(203, 150, kw["tile"] * 2):
            out.write(win.x, win.y, img[win.y : win.y + win.h, win.x : win.x + win.w])
    info = image_info(path)
    assert info.tiled and (info.width, info.height, info.channels) == (203, 150, 3)
    assert info.dtype == np.dtype(dtype)
    assert np.array_equal(read_image(path), img)
    for x, y, w, h in [(0, 0, 1, 1), (63, 31, 70, 90), (150, 100, 53, 50), (10, 149, 193, 1)]:
        assert np.array_equal(read_region(path, x, y, w, h), img[y : y + h, x : x + w])
    # Tiles with overlap: the core of each read window is the image's core.
    cores = np.zeros_like(img)

    def job(win, pix):
        assert pix.shape == (win.rh, win.rw, 3)
        assert np.array_equal(pix, img[win.ry : win.ry + win.rh, win.rx : win.rx + win.rw])
        return pix[win.core_in_read]

    def sink(win, core):
        cores[win.y : win.y + win.h, win.x : win.x + win.w] = core

    assert run_tiles(path, job, sink, tile=48, overlap=5) == 4 * 5
    assert np.array_equal(cores, img)
    if kw.get("bigtiff"):
        assert path.read_bytes()[2] == 43  # BigTIFF magic


def test_tile_windows_cover_once():
    wins = tile_windows(10, 7, (4, 3), overlap=2)
    hits = np.zeros((7, 10), int)
    for w in wins:
        hits[w.y : w.y + w.h, w.x : w.x + w.w] += 1
        assert w.rx == max(0, w.x - 2) and w.rx + w.rw == min(10, w.x + w.w + 2)
    assert (hits == 1).all()
    assert len(wins) == 3 * 3


def _box_filtered(path, shape, overlap, progress=None):
    """A 5 x 5 box filter run tile by tile, each tile's core kept."""
    out = np.zeros(shape, np.float32)

    def job(win, pix):
        box = ndimage.uniform_filter(pix[..., 0].astype(np.float32), size=5, mode="nearest")
        return box[win.core_in_read]

    def sink(win, core):
        out[win.y : win.y1, win.x : win.x1] = core

    run_tiles(path, job, sink, tile=40, overlap=overlap, progress=progress)
    return out


def test_tiles_with_overlap_equal_the_whole_image_filter(tmp_path):
    img = _ramp(97, 131, 1, np.uint8)
    path = tmp_path / "photo.tif"
    write_image(path, img, tile=32)
    whole = ndimage.uniform_filter(img[..., 0].astype(np.float32), size=5, mode="nearest")
    seen = []
    tiled = _box_filtered(path, whole.shape, 2, lambda d, t: seen.append((d, t)))
    assert np.allclose(tiled, whole, atol=1e-4)
    assert seen[0] == (0, 12) and seen[-1] == (12, 12)
    # Too little overlap shows at the tile borders.
    assert not np.allclose(_box_filtered(path, whole.shape, 0), whole, atol=1e-4)


def test_tiles_into_a_tiled_writer(tmp_path):
    img = _ramp(70, 90, 3, np.uint8)
    src = tmp_path / "in.tif"
    write_image(src, img)
    dst = tmp_path / "out.tif"
    with TiledImageWriter(dst, 90, 70, 3, np.uint8, tile=16) as out:
        run_tiles(src, lambda win, pix: 255 - pix, lambda win, res: out.write(win.x, win.y, res),
                  tile=32)
    assert np.array_equal(read_image(dst), 255 - img)


def test_run_tiles_sinks_each_tile_in_order(tmp_path):
    img = _ramp(64, 80, 3, np.uint8)
    path = tmp_path / "in.png"
    write_image(path, img)
    got = []
    n = run_tiles(path, lambda win, pix: int(pix.astype(np.int64).sum()),
                  lambda win, s: got.append((win.y, win.x, s)), tile=(30, 20))
    assert n == 3 * 4
    want = [(y, x, int(img[y : y + 20, x : x + 30].astype(np.int64).sum()))
            for y in range(0, 64, 20) for x in range(0, 80, 30)]
    assert got == want


def test_writer_errors(tmp_path):
    with pytest.raises(TerrathemeError, match="no tiles"):
        with TiledImageWriter(tmp_path / "x.png", 8, 8, 1):
            pass
    with pytest.raises(TerrathemeError, match="tile grid"):
        with TiledImageWriter(tmp_path / "x.tif", 64, 64, 1, tile=16) as out:
            out.write(3, 0, np.zeros((16, 16), np.uint8))
    assert not (tmp_path / "x.tif").exists()  # nothing half-written
    with pytest.raises(TerrathemeError, match="overlap"):
        tile_windows(4, 4, 2, overlap=-1)
    with pytest.raises(TerrathemeError, match="no pixels"):
        tile_windows(0, 4, 2)


@pytest.mark.parametrize(("channels", "dtype"), [(1, np.uint8), (3, np.uint8), (4, np.uint16)])
def test_georeference_round_trip_tiff(tmp_path, channels, dtype):
    img = _ramp(40, 60, channels, dtype)
    path = tmp_path / "a.tif"
    assert write_georeferenced(path, img, {}) == [] and read_georeference(path) == {}
    assert write_georeferenced(path, img, GEOREF) == [path]
    assert read_georeference(path) == GEOREF
    assert np.array_equal(read_image(path), img)
    # The tags go in with the pixels: nothing adds them to a TIFF already written.
    with pytest.raises(TerrathemeError, match="written with its pixels"):
        write_georeference(path, GEOREF)


def test_georeference_world_file_for_png(tmp_path):
    path = tmp_path / "preview.png"
    write_image(path, np.zeros((4, 4, 3), np.uint8))
    (made,) = write_georeference(path, GEOREF)
    assert made.suffix == ".pgw"
    # Centre of the top-left pixel: corner (1000, 2000) plus half a 0.5-unit pixel.
    assert [float(v) for v in made.read_text().split()] == [0.5, 0, 0, -0.5, 1000.25, 1999.75]
    scaled = scale_georeference(GEOREF, 4, 4)
    assert scaled["ModelPixelScale"] == [2.0, 2.0, 0.0]
    assert world_file_lines(scaled)[4:] == [1001.0, 1999.0]


def test_real_geotiff_georeference_kept(shared_data, tmp_path):
    src = shared_data / "geotiff" / "DRCOG_2020_LULC_E2880000_N1680000.tif"
    geo = read_georeference(src)
    assert geo["ModelPixelScale"][:2] == [1.0, 1.0]
    assert "GeoKeyDirectory" in geo and "GeoAsciiParams" in geo
    window = read_region(src, 4096, 4096, 300, 200)
    out = tmp_path / "crop.tif"
    assert write_georeferenced(out, window, geo) == [out]
    assert read_georeference(out) == geo
    assert np.array_equal(read_image(out), window)
