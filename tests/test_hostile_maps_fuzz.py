"""Fuzzing the new readers within the time and memory bound (issue 33): engine maps that
``new --from`` reads (Unity splatmaps, Unreal weight maps, Terrain3D control maps) and
projects whose colour map ships in tiles.

Every case runs in :class:`test_hostile_harness.BoundedReader` (256 MiB, 2 s CPU) and
must end in a grid or project, or one line naming the file.
"""

from __future__ import annotations

import json
import zipfile

import hostile_fuzz as fuzz
import numpy as np
import pytest
from hypothesis import strategies as st
from terratheme.core.exchange.terrain3d import write_control_map
from terratheme.core.io.codec import encode_image
from terratheme.core.io.images import write_image
from terratheme.core.model.colour_map import MAP_TILE, ColourMap, tile_boxes
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, save_project
from terratheme.core.themes.library import ThemeLibrary, flat_theme
from test_hostile_harness import shared_reader


@pytest.fixture(scope="module")
def bounded():
    return shared_reader()


def _map_bytes(tmp_path_factory, kind: str) -> bytes:
    rng = np.random.default_rng(3)
    folder = tmp_path_factory.mktemp(kind)
    if kind == "control":
        write_control_map(folder / "m.exr", rng.integers(0, 1 << 32, (9, 9), dtype=np.uint32))
        return (folder / "m.exr").read_bytes()
    image = (rng.integers(0, 255, (17, 17, 4), np.uint8) if kind == "splatmap"
             else rng.integers(0, 65535, (17, 17, 1), np.uint16))
    write_image(folder / "m.png", image)
    return (folder / "m.png").read_bytes()


MAPS = [("splatmap", ".png"), ("weights", ".png"), ("control", ".exr")]


@fuzz.campaign
@pytest.mark.parametrize(("kind", "suffix"), MAPS)
def test_truncations_of_engine_maps(budget, bounded, tmp_path_factory, tmp_path, kind, suffix):
    data = _map_bytes(tmp_path_factory, kind)
    kinds = fuzz.run_truncations(bounded, kind, data, tmp_path / f"cut{suffix}", budget,
                                 quick_cases=40)
    assert "error" in kinds


@fuzz.campaign
@pytest.mark.parametrize(("kind", "suffix"), MAPS)
def test_flips_and_insertions_in_engine_maps(budget, bounded, tmp_path_factory, tmp_path, kind,
                                             suffix):
    data = _map_bytes(tmp_path_factory, kind)
    budget.explore(lambda edits: fuzz.run_edited(bounded, kind, data, tmp_path / f"m{suffix}",
                                                 edits), edits=fuzz.EDITS)


@pytest.fixture(scope="module")
def tiled(tmp_path_factory) -> bytes:
    """A 1.9 KB project whose 4097 x 1 colour map ships in two MAP_TILE tiles."""
    cell, scale = 256, 4096
    gw = -(-(MAP_TILE * scale + 1) // cell)
    grid = IndexGrid(np.zeros((2, gw + 1), np.uint8), (cell, cell))
    shape = ColourMap.shape_for(grid.texture_size, scale)
    pixels = np.full((*shape, 3), 128, np.uint8)
    pixels[:, :96] = np.arange(96, dtype=np.uint8)[None, :, None] + 80
    tiles = tuple(encode_image(np.ascontiguousarray(pixels[box]), codec="png")
                  for box in tile_boxes(shape, MAP_TILE))
    project = ThematicTexture(grid, ThemeLibrary([flat_theme("a", (1, 2, 3))]),
                              colour_map=ColourMap(pixels, scale, "png", None, tiles, MAP_TILE))
    path = tmp_path_factory.mktemp("tiled") / "t.ttproj"
    save_project(path, project)
    return path.read_bytes()


def test_the_tiled_sample_loads(bounded, tiled, tmp_path):
    assert len(tiled) < 4000
    assert fuzz.run_bytes(bounded, "project", tmp_path / "t.ttproj", tiled).kind == "ok"


@fuzz.campaign
def test_truncations_of_a_tiled_colour_map_project(budget, bounded, tiled, tmp_path):
    kinds = fuzz.run_truncations(bounded, "project", tiled, tmp_path / "cut.ttproj", budget,
                                 quick_cases=len(tiled) // 10)
    assert kinds == {"error"}


@fuzz.campaign
def test_flips_in_a_tiled_colour_map_project(budget, bounded, tiled, tmp_path):
    budget.explore(lambda edits: fuzz.run_edited(bounded, "project", tiled,
                                                 tmp_path / "mut.ttproj", edits),
                   edits=fuzz.EDITS)


def _with_entry(data: bytes, path, change, extra: dict | None = None) -> bytes:
    """The project ``data`` with its manifest's colour_map entry changed by ``change`` (and
    ``extra`` members added)."""
    src = path.with_suffix(".src")
    src.write_bytes(data)
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(path, "w") as zout:
        manifest = json.loads(zin.read("manifest.json"))
        change(manifest["colour_map"])
        zout.writestr("manifest.json", json.dumps(manifest))
        for name in zin.namelist():
            if name != "manifest.json":
                zout.writestr(name, zin.read(name))
        for name, member in (extra or {}).items():
            zout.writestr(name, member)
    return path.read_bytes()


def test_one_small_member_listed_per_pixel_is_bounded(bounded, tiled, tmp_path):
    # Found: "tile": 1 and one 1 x 1 member listed once per map pixel decoded it 4097 times
    # (7 s to 12 min, by the manifest's size).
    pixel = encode_image(np.full((1, 1, 3), 128, np.uint8), codec="png")
    data = _with_entry(tiled, tmp_path / "px.ttproj",
                       lambda e: e.update(tile=1, members=["colour_map/px.png"] * 4097),
                       {"colour_map/px.png": pixel})
    outcome = fuzz.run_bytes(bounded, "project", tmp_path / "px.ttproj", data)
    assert outcome.kind == "error" and "tiles of 1 pixels" in outcome.message, outcome


#: values put in a tiled colour map's fields (the "tile": 1 case listed one member per pixel)
FIELD_VALUES = (st.sampled_from([0, 1, 2, 16, 4095, 4097, MAP_TILE, 1 << 20, -1, True, 2.5,
                                 "4096", None, []])
                | st.integers(-(1 << 40), 1 << 40))
MEMBER_LISTS = st.sampled_from(["repeat", "reverse", "drop", "extra", "many"])


def _members(entry: dict, how: str) -> None:
    names = entry["members"]
    entry["members"] = {"repeat": [names[0]] * len(names), "reverse": names[::-1],
                        "drop": names[:1], "extra": [*names, "grid.npy"],
                        "many": [names[0]] * 5000}[how]


@fuzz.campaign
def test_hostile_tiled_colour_map_entries(budget, bounded, tiled, tmp_path):
    def case(field, value, members):
        def change(entry):
            if field == "members":
                _members(entry, members)
            else:
                entry[field] = value
        fuzz.run_bytes(bounded, "project", tmp_path / "e.ttproj",
                       _with_entry(tiled, tmp_path / "e.ttproj", change))

    budget.explore(case, field=st.sampled_from(["tile", "scale", "members", "codec"]),
                   value=FIELD_VALUES, members=MEMBER_LISTS)
