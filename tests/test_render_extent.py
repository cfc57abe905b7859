"""Renders of a converted project: the photo's size and its georeference."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.georef import read_georeference, scale_georeference, world_file_lines
from terratheme.core.io.images import read_image
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, save_project
from terratheme.core.render.project import photo_extent, render_georeference
from terratheme.core.themes.library import ThemeLibrary, flat_theme

GEO = {"ModelPixelScale": [2.0, 2.0, 0.0], "ModelTiepoint": [0.0, 0.0, 0.0, 500.0, 900.0, 0.0]}


def _project(meta: dict) -> ThematicTexture:
    grid = IndexGrid(np.array([[0, 1, 1], [0, 0, 1]], np.uint8), (16, 16))  # 32 x 16 texels
    lib = ThemeLibrary([flat_theme("a", (10, 20, 30)), flat_theme("b", (200, 100, 50))])
    return ThematicTexture(grid, lib, meta)


def test_extent_is_the_photo_size_cut_to_the_texture():
    assert photo_extent(_project({"photo_size": [27, 13]})) == (27, 13)
    assert photo_extent(_project({"photo_size": [40, 13]})) == (32, 13)
    assert photo_extent(_project({})) == (32, 16)
    assert photo_extent(_project({"photo_size": (27.0, 13)})) == (27, 13)


@pytest.mark.parametrize("size", ["big", "12", [27], [27, 13, 1], [0, 13], [27, -1], [27.5, 13],
                                  [True, 13], ["27", 13], [float("nan"), 13], None])
def test_a_photo_size_that_is_not_two_positive_whole_numbers_is_refused(size):
    project = _project({"photo_size": size})
    if size is None:
        assert photo_extent(project) == (32, 16)  # absent: the texture's extent
        return
    with pytest.raises(TerrathemeError, match="photo_size must be two positive whole numbers"):
        photo_extent(project)


def test_region_georeference_moves_the_tie_point_and_scales():
    geo = scale_georeference(GEO, 1.0, 1.0, offset=(3, 5))
    # Old pixel (3, 5) is the new corner: 500 + 3*2, 900 - 5*2.
    assert geo["ModelTiepoint"][3:5] == [506.0, 890.0]
    both = scale_georeference(GEO, 2.0, 4.0, offset=(3, 5))
    assert both["ModelPixelScale"][:2] == [4.0, 8.0]
    assert world_file_lines(both)[4:] == [508.0, 886.0]


def test_world_file_of_pixel_is_point_and_pixel_is_area():
    # GTRasterTypeGeoKey (1025) 2: the tie point is pixel (0, 0)'s centre; 1 (or absent): its
    # top-left corner, so the centre lies half a pixel (1 unit) right and down.
    point = {**GEO, "GeoKeyDirectory": [1, 1, 0, 2, 1024, 0, 1, 1, 1025, 0, 1, 2]}
    area = {**GEO, "GeoKeyDirectory": [1, 1, 0, 2, 1024, 0, 1, 1, 1025, 0, 1, 1]}
    assert world_file_lines(point) == [2.0, 0.0, 0.0, -2.0, 500.0, 900.0]
    assert world_file_lines(area) == [2.0, 0.0, 0.0, -2.0, 501.0, 899.0]
    assert world_file_lines(GEO) == world_file_lines(area)


def test_world_file_of_a_rotated_transformation():
    # 2-unit pixels turned 30 degrees: x = 1.732 i + 1 j + 500, y = 1 i - 1.732 j + 900.
    c, s = 2 * np.sqrt(3) / 2, 1.0
    turned = {"ModelTransformation": [c, s, 0, 500.0, s, -c, 0, 900.0, 0, 0, 0, 0, 0, 0, 0, 1]}
    # A, D, B, E, then pixel (0, 0)'s centre (i = j = 1/2): 500 + (1.732 + 1) / 2,
    # 900 + (1 - 1.732) / 2.
    assert world_file_lines(turned) == pytest.approx(
        [1.7320508, 1.0, 1.0, -1.7320508, 501.3660254, 899.6339746])
    from terratheme.core.exchange import world_frame

    frame = world_frame(turned, (10, 10))
    assert frame.rotation_deg == pytest.approx(30.0)
    assert frame.texel_size == pytest.approx((2.0, 2.0))
    assert frame.origin == pytest.approx((501.3660254, 899.6339746))


def test_transformation_georeference_offset_matches_the_tie_point_form():
    affine = {"ModelTransformation": [2.0, 0, 0, 500.0, 0, -2.0, 0, 900.0, 0, 0, 0, 0, 0, 0, 0, 1]}
    a = world_file_lines(scale_georeference(affine, 2.0, 2.0, offset=(3, 5)))
    b = world_file_lines(scale_georeference(GEO, 2.0, 2.0, offset=(3, 5)))
    assert a == pytest.approx(b)


def test_render_georeference_of_a_region_and_scale():
    proj = _project({"georeference": GEO, "photo_size": [27, 13]})
    geo = render_georeference(proj, (4, 2, 20, 10), (10, 5))
    assert geo["ModelPixelScale"][:2] == [4.0, 4.0]
    assert geo["ModelTiepoint"][3:5] == [508.0, 896.0]
    assert render_georeference(_project({}), (0, 0, 32, 16), (32, 16)) == {}


def test_cli_render_gives_the_photo_size_with_a_world_file(tmp_path, capsys):
    path = tmp_path / "p.ttproj"
    save_project(path, _project({"georeference": GEO, "photo_size": [27, 13]}))
    out = tmp_path / "r.png"
    assert main(["render", str(path), str(out)]) == 0
    assert read_image(out).shape == (13, 27, 3)
    world = [float(v) for v in (tmp_path / "r.pgw").read_text().split()]
    assert world == [2.0, 0.0, 0.0, -2.0, 501.0, 899.0]
    assert "georeference" in capsys.readouterr().out
    # A GeoTIFF render carries the tags; a region moves them.
    tif = tmp_path / "r.tif"
    assert main(["render", str(path), str(tif), "--region", "4,2,8,8"]) == 0
    assert read_image(tif).shape == (8, 8, 3)
    assert read_georeference(tif)["ModelTiepoint"][3:5] == [508.0, 896.0]


def test_a_project_with_a_bad_photo_size_is_one_line_naming_it(tmp_path, capsys):
    save_project(tmp_path / "p.ttproj", _project({"photo_size": [27, "wide"]}))
    assert main(["render", str(tmp_path / "p.ttproj"), str(tmp_path / "o.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "p.ttproj: metadata photo_size" in err
    assert not (tmp_path / "o.png").exists()
