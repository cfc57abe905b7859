"""``terratheme export`` and the way back through ``terratheme new``: round trips and errors."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.io.images import write_image
from terratheme.core.model.project import load_project, save_project

THEMES = "water,sand,forest,grass,town"


@pytest.fixture
def project(tmp_path):
    """A project made by ``new`` from an index image: 8 x 8 vertices, cell 9 (63 texels)."""
    rng = np.random.default_rng(21)
    grid = rng.integers(0, 5, (8, 8)).astype(np.uint8)
    write_image(tmp_path / "index.png", grid[:, :, None])
    path = tmp_path / "p.ttproj"
    assert main(["new", str(tmp_path / "index.png"), str(path), "--themes", THEMES,
                 "--cell", "9"]) == 0
    return path, grid


def _error(capsys, argv, match):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and match in err, err


def test_unity_export_and_back(tmp_path, project, capsys):
    path, grid = project
    out = tmp_path / "unity"
    assert main(["export", str(path), str(out), "--engine", "unity"]) == 0
    assert "64 x 64 map" in capsys.readouterr().out
    back = tmp_path / "back.ttproj"
    assert main(["new", str(out / "splatmap_0.png"), str(out / "splatmap_1.png"), str(back),
                 "--themes", THEMES, "--from", "splatmap", "--step", "9", "--cell", "9"]) == 0
    np.testing.assert_array_equal(load_project(back).grid.indices, grid)


def test_unreal_tiles_export_and_back(tmp_path, capsys):
    # 15 x 15 vertices of cell 9: 126 texels, one recommended 127 landscape.
    grid = np.random.default_rng(5).integers(0, 3, (15, 15)).astype(np.uint8)
    write_image(tmp_path / "index.png", grid[:, :, None])
    path = tmp_path / "p.ttproj"
    assert main(["new", str(tmp_path / "index.png"), str(path), "--themes", "water,sand,rock",
                 "--cell", "9"]) == 0
    out = tmp_path / "unreal"
    assert main(["export", str(path), str(out), "--engine", "unreal"]) == 0
    maps = [str(out / f"weight_{k:02d}_{n}.png") for k, n in enumerate(["water", "sand", "rock"])]
    back = tmp_path / "back.ttproj"
    assert main(["new", *maps, str(back), "--themes", "water,sand,rock", "--from", "weights",
                 "--step", "9", "--cell", "9"]) == 0
    np.testing.assert_array_equal(load_project(back).grid.indices, grid)
    capsys.readouterr()
    _error(capsys, ["new", *maps[:2], str(back), "--themes", "water,sand,rock", "--from",
                    "weights"], "one weight map per theme: 2 maps for 3 themes")
    _error(capsys, ["new", *maps, str(back), "--themes", "water,sand,rock", "--from", "weights",
                    "--step", "10"], "multiples of the step")


def test_terrain3d_export_and_back(tmp_path, project):
    path, grid = project
    out = tmp_path / "godot"
    assert main(["export", str(path), str(out), "--engine", "godot"]) == 0
    back = tmp_path / "back.ttproj"
    assert main(["new", str(out / "terrain3d_control.exr"), str(back), "--themes", THEMES,
                 "--from", "terrain3d", "--cell", "9"]) == 0
    p = load_project(back)
    np.testing.assert_array_equal(p.grid.indices, grid)
    assert p.grid.cell == (9, 9) and p.metadata["source_kind"] == "terrain3d"


def test_geotiff_export(tmp_path, project, capsys):
    path, _ = project
    assert main(["export", str(path), str(tmp_path / "gis"), "--engine", "geotiff"]) == 0
    out = capsys.readouterr().out
    assert "land-class map and baked texture" in out and "no georeference" in out
    assert (tmp_path / "gis" / "texture.tif").is_file()


def test_errors_are_one_line_and_write_nothing(tmp_path, project, capsys):
    path, _ = project
    capsys.readouterr()
    _error(capsys, ["export", str(path), str(tmp_path / "x"), "--engine", "unity",
                    "--size", "100x100"], "--size 100 is not a Unity alphamap resolution")
    assert not (tmp_path / "x").exists()
    _error(capsys, ["export", str(path), str(tmp_path / "x"), "--engine", "unreal",
                    "--tile", "100"], "--tile 100 is not a recommended Unreal landscape size")
    _error(capsys, ["export", str(path), str(tmp_path / "x"), "--engine", "godot",
                    "--tile", "64"], "export it without --tile")
    _error(capsys, ["export", str(path), str(tmp_path / "x"), "--engine", "geotiff",
                    "--size", "64x64"], "--size and --tile are for engine exports")
    assert not (tmp_path / "x").exists()
    _error(capsys, ["export", str(path), str(path), "--engine", "unity"], "is a file")
    _error(capsys, ["export", str(tmp_path / "none.ttproj"), str(tmp_path / "y"), "--engine",
                    "godot"], "no such project file")
    loop = tmp_path / "loop.ttproj"
    loop.symlink_to(loop)
    _error(capsys, ["export", str(loop), str(tmp_path / "y"), "--engine", "godot"],
           "loop.ttproj: cannot be read (a symlink loop)")
    assert main(["info", str(loop)]) == 2
    assert "cannot be read (a symlink loop)" in capsys.readouterr().err
    # An export must not overwrite its own input, even one named like an output.
    gis = tmp_path / "gis"
    gis.mkdir()
    save_project(gis / "texture.tif", load_project(path))
    _error(capsys, ["export", str(gis / "texture.tif"), str(gis), "--engine", "geotiff"],
           "is also an input")
    index = tmp_path / "index.png"
    _error(capsys, ["new", str(index), str(index), "--themes", THEMES], "is also an input")
    _error(capsys, ["new", str(index), str(tmp_path / "a.ttproj"), "--themes", THEMES,
                    "--step", "2"], "--step is for engine maps")
    _error(capsys, ["new", str(index), str(index), str(tmp_path / "a.ttproj"), "--themes",
                    THEMES, "--from", "terrain3d"], "reads one map, got 2")
    _error(capsys, ["new", str(index), str(tmp_path / "a.ttproj"), "--themes", THEMES,
                    "--from", "terrain3d"], "32-bit floats")


def test_splatmap_channel_without_a_theme_is_refused(tmp_path, capsys):
    rgba = np.zeros((5, 5, 4), np.uint8)
    rgba[:, :, 0] = 200
    rgba[:, :, 2] = 55  # weight in channel 2, but only two themes are named
    write_image(tmp_path / "s.png", rgba, attributes={"oiio:UnassociatedAlpha": 1})
    _error(capsys, ["new", str(tmp_path / "s.png"), str(tmp_path / "a.ttproj"), "--themes",
                    "water,sand", "--from", "splatmap"], "weight channel 2 carries weight")


def test_a_styled_project_exports_its_look_and_comes_back(tmp_path, project, capsys):
    # The project as convert leaves it: shaped borders in metadata["render"] and a colour map.
    from terratheme.core.model.colour_map import ColourMap

    path, grid = project
    p = load_project(path)
    p.metadata["render"] = {"boundary": {"width": 3.0, "noise": 90, "height": 40,
                                         "features": 2.0, "seed": 0}}
    p.colour_map = ColourMap(np.random.default_rng(1).integers(90, 170, (8, 8, 3))
                             .astype(np.uint8), 8)
    save_project(path, p)
    capsys.readouterr()
    out = tmp_path / "unity"
    assert main(["export", str(path), str(out), "--engine", "unity"]) == 0
    assert "shaped borders, colour map" in capsys.readouterr().out
    assert (out / "colour_map.png").is_file()
    back = tmp_path / "back.ttproj"
    assert main(["new", str(out / "splatmap_0.png"), str(out / "splatmap_1.png"), str(back),
                 "--themes", THEMES, "--from", "splatmap", "--step", "9", "--cell", "9"]) == 0
    np.testing.assert_array_equal(load_project(back).grid.indices, grid)
    linear = tmp_path / "linear"
    assert main(["export", str(path), str(linear), "--engine", "unity", "--style", "linear"]) == 0
    assert "linear weights, colour map" in capsys.readouterr().out
    assert (out / "splatmap_0.png").read_bytes() != (linear / "splatmap_0.png").read_bytes()
    p.metadata["render"] = {"boundary": {"width": "wide"}}
    save_project(path, p)
    _error(capsys, ["export", str(path), str(tmp_path / "bad"), "--engine", "godot"],
           "boundary")
    assert not (tmp_path / "bad").exists()
