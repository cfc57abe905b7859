"""``terratheme info PROJECT``: grid, themes, colour map, style and bytes of a project."""

from __future__ import annotations

import json

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.io.images import write_image
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, save_project
from terratheme.core.themes.library import ThemeLibrary, flat_theme


def _project(colour_map=None) -> ThematicTexture:
    indices = np.zeros((4, 7), np.uint8)  # 4 x 7 vertices: 3 x 6 cells of 16 x 8 texels
    indices[:, 4:] = 1
    library = ThemeLibrary([flat_theme("sand", (225, 200, 140), size=8),
                            flat_theme("water", (40, 90, 200), size=12)])
    return ThematicTexture(IndexGrid(indices, cell=(16, 8)), library,
                           metadata={"georeference": {"crs": "EPSG:32640"}},
                           colour_map=colour_map)


def _info(tmp_path, capsys, project, *extra):
    path = tmp_path / "p.ttproj"
    save_project(path, project)
    assert main(["info", str(path), "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_the_grid_and_themes_as_stored(tmp_path, capsys):
    info = _info(tmp_path, capsys, _project())
    assert info["vertices"] == [7, 4] and info["cell"] == [16, 8]
    assert info["texture_size"] == [6 * 16, 3 * 8]
    assert [(t["index"], t["name"], t["size"]) for t in info["themes"]] == [
        (0, "sand", [8, 8]), (1, "water", [12, 12])]
    assert info["colour_map"] is None and info["colour_map_bytes"] == 0
    assert info["georeference"] == {"crs": "EPSG:32640"}
    assert info["layers"] == []


def test_bytes_are_the_packed_grid_plus_the_colour_map(tmp_path, capsys):
    project = _project(ColourMap(np.full((2, 6, 3), 128, np.uint8), 16))
    info = _info(tmp_path, capsys, project)
    assert info["colour_map"]["scale"] == 16 and info["colour_map"]["size"] == [6, 2]
    # A raw map ships as its pixels (colour_map.npy): 2 x 6 x 3 bytes.
    assert info["colour_map_bytes"] == 36
    assert info["area_bytes"] == info["grid_bytes"] + info["colour_map_bytes"]
    # The grid's bytes are those of the layer file `terratheme pack` writes of it.
    grid_png, packed = tmp_path / "grid.png", tmp_path / "grid.ttpack"
    write_image(grid_png, project.grid.indices)
    assert main(["pack", str(grid_png), str(packed)]) == 0
    assert info["grid_bytes"] == packed.stat().st_size
    assert info["theme_bytes"] > 0


def test_a_predicted_map_is_named_and_counted_as_it_ships(tmp_path, capsys):
    from terratheme.core.model.map_prediction import class_colours, class_prediction

    plain = _project()
    stored = np.full((2, 6, 3), 90, np.uint8)
    stored[:, 4:] = 170
    grid = plain.grid
    colours = class_colours(stored, grid.indices, grid.cell, 16, 2)
    prediction = class_prediction(grid.indices, grid.cell, colours, 16, (2, 6))
    cmap = ColourMap.encode(stored, 16, "avif", 80, colours=colours, prediction=prediction)
    info = _info(tmp_path, capsys, _project(cmap))
    assert info["colour_map"]["predicted"] is True and info["colour_map"]["codec"] == "avif"
    assert info["colour_map_bytes"] == len(cmap.data)
    plain_info = _info(tmp_path, capsys, _project(ColourMap(stored, 16)))
    assert plain_info["colour_map"]["predicted"] is False


def test_plain_text_lists_the_same_fields(tmp_path, capsys):
    path = tmp_path / "p.ttproj"
    save_project(path, _project())
    assert main(["info", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "vertices: [7, 4]" in lines and any(line.startswith("area_bytes: ") for line in lines)


def test_runs_are_for_packed_layers_only(tmp_path, capsys):
    path = tmp_path / "p.ttproj"
    save_project(path, _project())
    assert main(["info", str(path), "--runs"]) == 2
    assert "a project has none" in capsys.readouterr().err


def test_a_damaged_project_is_one_line(tmp_path, capsys):
    path = tmp_path / "bad.ttproj"
    path.write_bytes(b"PK\x03\x04 not really")
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.ttproj" in err


@pytest.mark.parametrize("suffix", [".TTPROJ", ".ttproj"])
def test_the_suffix_picks_the_reader(tmp_path, capsys, suffix):
    path = tmp_path / f"p{suffix}"
    save_project(path, _project())
    assert main(["info", str(path), "--json"]) == 0
    assert "themes" in json.loads(capsys.readouterr().out)
