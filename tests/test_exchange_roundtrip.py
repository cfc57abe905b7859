"""Every export comes back with ``new`` (its folder or manifest) to the same project.

A converted photo (themes cut from the photo, a colour map) goes out through
each engine and back: the grid, the cell, the themes (names, display colours,
texels) and the colour map (pixels, scale, its codec's bytes) are the same.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.convert.photo import convert_photo
from terratheme.core.model.project import load_project, save_project

ENGINES = ("unity", "unreal", "godot", "geotiff")


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    rng = np.random.default_rng(2)
    photo = rng.integers(0, 40, (160, 192, 3), dtype=np.uint8)
    photo[:, 64:] += np.array([150, 120, 40], np.uint8)
    photo[80:, 128:] = rng.integers(20, 60, (80, 64, 3), dtype=np.uint8) + np.array(
        [0, 60, 160], np.uint8)
    project = convert_photo(photo).project
    assert project.colour_map is not None
    assert any("photo" in t.source or "quilted" in t.source for t in project.library)
    path = tmp_path_factory.mktemp("p") / "photo.ttproj"
    save_project(path, project)
    return path


def _same(a, b) -> None:
    np.testing.assert_array_equal(a.grid.indices, b.grid.indices)
    assert a.grid.cell == b.grid.cell
    assert a.library.names == b.library.names
    np.testing.assert_array_equal(a.library.colours, b.library.colours)
    for ta, tb in zip(a.library, b.library, strict=True):
        np.testing.assert_array_equal(ta.texture, tb.texture)
    ca, cb = a.colour_map, b.colour_map
    np.testing.assert_array_equal(ca.pixels, cb.pixels)
    assert (ca.scale, ca.codec, ca.data) == (cb.scale, cb.codec, cb.data)


@pytest.mark.parametrize("engine", ENGINES)
def test_an_export_comes_back_to_the_same_project(converted, tmp_path, engine, capsys):
    out = tmp_path / engine
    assert main(["export", str(converted), str(out), "--engine", engine]) == 0
    (manifest,) = out.glob("terratheme_*.json")
    original = load_project(converted)
    for source, name in ((out, "a.ttproj"), (manifest, "b.ttproj")):
        assert main(["new", str(source), str(tmp_path / name)]) == 0, capsys.readouterr().err
        _same(original, load_project(tmp_path / name))
    assert main(["new", str(out), str(tmp_path / "c.ttproj"), "--from", "export"]) == 0


def test_a_manifest_without_a_carried_project_is_one_line(converted, tmp_path, capsys):
    out = tmp_path / "u"
    assert main(["export", str(converted), str(out), "--engine", "unity"]) == 0
    manifest = out / "terratheme_unity.json"
    data = json.loads(manifest.read_text())
    for value, words in ((None, "carries no project"), ("../photo.ttproj", "a file name"),
                         ("terratheme_unity.json", "cannot")):
        if value is None:
            data.pop("project")
        else:
            data["project"] = value
        manifest.write_text(json.dumps(data))
        capsys.readouterr()
        assert main(["new", str(manifest), str(tmp_path / "x.ttproj")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
        if words != "cannot":
            assert words in err, err


def test_a_folder_mixing_two_exports_is_refused(converted, tmp_path, capsys):
    out = tmp_path / "u"
    assert main(["export", str(converted), str(out), "--engine", "unity"]) == 0
    data = json.loads((out / "terratheme_unity.json").read_text())
    data["grid_shape"] = [data["grid_shape"][0] + 1, data["grid_shape"][1]]
    (out / "terratheme_unity.json").write_text(json.dumps(data))
    assert main(["new", str(out), str(tmp_path / "x.ttproj")]) == 2
    assert "mixes two exports" in capsys.readouterr().err


def test_new_without_themes_needs_them_except_for_an_export(tmp_path, capsys):
    assert main(["new", "map.png", str(tmp_path / "p.ttproj")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("terratheme new: error: --themes is needed") and err.count("\n") == 1


def test_the_gis_export_writes_the_colour_map_as_a_geotiff(converted, tmp_path):
    from terratheme.core.io.images import read_image

    out = tmp_path / "gis"
    assert main(["export", str(converted), str(out), "--engine", "geotiff"]) == 0
    cmap = load_project(converted).colour_map
    np.testing.assert_array_equal(read_image(out / "colour_map.tif"), cmap.pixels)
    manifest = json.loads((out / "terratheme_geotiff.json").read_text())
    assert manifest["colour_map"]["file"] == "colour_map.tif"
    assert manifest["colour_map"]["scale"] == cmap.scale


def test_godot_says_what_a_control_map_per_vertex_carries(converted, tmp_path, capsys):
    from terratheme.core.exchange import decode_control
    from terratheme.core.io.images import read_image

    def read_control_map(path):
        return read_image(path)[:, :, 0].copy().view(np.uint32)

    gh, gw = load_project(converted).grid.indices.shape
    out = tmp_path / "g"
    assert main(["export", str(converted), str(out), "--engine", "godot"]) == 0
    said = capsys.readouterr().out
    assert "shaped borders" not in said.splitlines()[0] and "vertex themes only" in said
    assert json.loads((out / "terratheme_godot.json").read_text())["borders"] == "vertex"
    assert not decode_control(read_control_map(out / "terrain3d_control.exr")).blend.any()
    # A vertex per texel carries the shaped borders' blend.
    w, h = load_project(converted).grid.texture_size
    fine = tmp_path / "f"
    assert main(["export", str(converted), str(fine), "--engine", "godot", "--size",
                 f"{w + 1}x{h + 1}"]) == 0
    assert "shaped borders" in capsys.readouterr().out
    assert json.loads((fine / "terratheme_godot.json").read_text())["borders"] == "shaped"
    assert decode_control(read_control_map(fine / "terrain3d_control.exr")).blend.any()
    assert (gw, gh) != (w + 1, h + 1)



def test_maps_read_from_an_export_point_at_the_exact_way_back(tmp_path, capsys):
    from pathlib import Path

    samples = Path(__file__).resolve().parents[1] / "sample_maps"
    themes = "water,sand,grass,forest,town,road"
    assert main(["new", str(samples / "coastline.png"), str(tmp_path / "c.ttproj"), "--themes",
                 themes, "--cell", "4"]) == 0
    out = tmp_path / "u"
    assert main(["export", str(tmp_path / "c.ttproj"), str(out), "--engine", "unity"]) == 0
    capsys.readouterr()
    maps = sorted(str(p) for p in out.glob("splatmap_*.png"))
    assert main(["new", *maps, str(tmp_path / "m.ttproj"), "--from", "splatmap",
                 "--themes", themes]) == 0
    assert f"'terratheme new {out} PROJECT' brings back" in capsys.readouterr().out
