"""Renders larger than memory: a tiled GeoTIFF with overviews, band by band, bounded memory."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
import terratheme.app.commands.render as render_command
import tifffile
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange.texture_tiff import TILE, write_texture_tiff
from terratheme.core.io.georef import read_georeference, scale_georeference
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, save_project
from terratheme.core.render.project import render_project
from terratheme.core.themes.library import shipped_theme_library

GEOREF = {
    "ModelPixelScale": [1.0, 1.0, 0.0],
    "ModelTiepoint": [0.0, 0.0, 0.0, 300000.0, 2800000.0, 0.0],
    "GeoKeyDirectory": [1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32640],
    "GeoAsciiParams": "WGS 84 / UTM zone 40N|",
}


def _project(cells=(40, 56), cell=16, seed=4, colour=True, georef=True) -> ThematicTexture:
    """A converted-looking project: shaped borders, a colour map, a georeference."""
    rng = np.random.default_rng(seed)
    coarse = rng.integers(0, 4, (cells[0] // 4 + 1, cells[1] // 4 + 1))
    grid = np.kron(coarse, np.ones((4, 4), int))[: cells[0] + 1, : cells[1] + 1]
    grid = IndexGrid(grid.astype(np.uint8), (cell, cell))
    meta = {"render": {"boundary": {}}, "photo_size": [cells[1] * cell - 5, cells[0] * cell - 3]}
    if georef:
        meta["georeference"] = GEOREF
    cmap = None
    if colour:
        mh, mw = ColourMap.shape_for(grid.texture_size, 64)
        cmap = ColourMap(rng.integers(100, 160, (mh, mw, 3), dtype=np.uint8), 64)
    library = shipped_theme_library().select(("water", "sand", "forest", "town"))
    return ThematicTexture(grid, library, meta, colour_map=cmap)


def test_tiled_render_is_the_whole_render_with_box_overviews(tmp_path):
    project = _project()
    region = (37, 21, 700, 600)
    out = tmp_path / "r.tif"
    bands = []
    size, overviews = write_texture_tiff(project, out, region,
                                         progress=lambda d, t: bands.append((d, t)))
    want = render_project(project, region)
    assert size == (700, 600) and overviews == 1
    assert bands == [(1, 2), (2, 2)]  # two bands of TILE rows
    with tifffile.TiffFile(out) as tif:
        pages = list(tif.pages)
        assert [p.shape for p in pages] == [(600, 700, 3), (300, 350, 3)]
        assert [p.subfiletype for p in pages] == [0, 1]
        assert pages[0].is_tiled and pages[0].tilewidth == TILE
        np.testing.assert_array_equal(pages[0].asarray(), want)
        half = pages[1].asarray().astype(int)
    mean = want.reshape(300, 2, 350, 2, 3).mean(axis=(1, 3))
    assert np.abs(half - mean).max() <= 0.5
    # The region's corner carries the tie point: 37 m east, 21 m south of the photo's.
    geo = read_georeference(out)
    assert geo["ModelTiepoint"][3:5] == [300037.0, 2799979.0]
    assert geo == {**GEOREF, **scale_georeference(GEOREF, 1, 1, offset=(37, 21))}


def test_memory_is_set_by_the_band_not_the_height(tmp_path):
    peaks = {}
    for rows in (TILE, 4 * TILE, 16 * TILE):
        project = _project(cells=(rows // 16, 64), colour=False, georef=False)
        tracemalloc.start()
        write_texture_tiff(project, tmp_path / f"{rows}.tif", (0, 0, 1024, rows))
        peaks[rows] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    # (The first run also holds the first use's allocations.) Four times the rows and
    # the output, 24 MiB of pixels, not four times the memory: a few bands' worth.
    assert peaks[16 * TILE] < 1.1 * peaks[4 * TILE]
    assert peaks[16 * TILE] < 8 * 1024 * TILE * 3


def test_too_large_for_the_writer_is_refused_before_work(tmp_path):
    big = ThematicTexture(IndexGrid(np.zeros((2401, 2401), np.uint8), (16, 16)),
                          shipped_theme_library().select(("sand",)), {})
    with pytest.raises(TerrathemeError,
                       match=r"38400 x 38400 render is 4\.1 GiB.*regions \(region\)"):
        write_texture_tiff(big, tmp_path / "big.tif")
    assert not list(tmp_path.iterdir())


def test_cli_streams_tif_above_the_size_and_with_tiled(tmp_path, capsys, monkeypatch):
    project = _project()
    path = tmp_path / "p.ttproj"
    save_project(path, project)
    w, h = project.metadata["photo_size"]
    whole = render_project(project, (0, 0, w, h))
    # --tiled: the streamed GeoTIFF with overviews.
    assert main(["render", str(path), str(tmp_path / "a.tif"), "--tiled"]) == 0
    said = capsys.readouterr().out
    assert f"{w} x {h} texels (shaped blend), tiled GeoTIFF with 1 overview" in said
    with tifffile.TiffFile(tmp_path / "a.tif") as tif:
        assert len(tif.pages) == 2
        np.testing.assert_array_equal(tif.pages.first.asarray(), whole)
    # Above STREAM_TEXELS a .tif is streamed by itself; a .png or a scaled render is not.
    monkeypatch.setattr(render_command, "STREAM_TEXELS", 1000)
    assert main(["render", str(path), str(tmp_path / "b.tif")]) == 0
    assert "tiled GeoTIFF" in capsys.readouterr().out
    assert (tmp_path / "b.tif").read_bytes() == (tmp_path / "a.tif").read_bytes()
    assert main(["render", str(path), str(tmp_path / "c.tif"), "--scale", "0.5"]) == 0
    assert main(["render", str(path), str(tmp_path / "d.png")]) == 0
    assert "tiled" not in capsys.readouterr().out
    with tifffile.TiffFile(tmp_path / "c.tif") as tif:
        assert len(tif.pages) == 1


def test_cli_tiled_errors(tmp_path, capsys):
    path = tmp_path / "p.ttproj"
    save_project(path, _project(colour=False))
    for extra, message in [
        (["x.png", "--tiled"], "--tiled writes a GeoTIFF: name it .tif"),
        (["x.tif", "--tiled", "--scale", "0.5"], "drop --scale and --gpu"),
        (["x.tif", "--tiled", "--gpu"], "drop --scale and --gpu"),
        (["x.tif", "--tiled", "--region", "0,0,9000,10"], "outside the 896 x 640 texture"),
    ]:
        assert main(["render", str(path), str(tmp_path / extra[0]), *extra[1:]]) == 2
        assert message in capsys.readouterr().err
    assert not list(tmp_path.glob("x*"))
