"""``terratheme convert`` end to end on tiny synthetic photos, and the pipeline's failure cases."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from terratheme.app.cli import main
from terratheme.app.commands.convert import parse_themes
from terratheme.core.convert.colour_fit import MIN_AREA_BYTES
from terratheme.core.convert.photo import ConvertOptions, convert_photo
from terratheme.core.errors import TerrathemeError
from terratheme.core.fidelity import texture_cost
from terratheme.core.io.georef import read_georeference, tiff_extratags, write_georeferenced
from terratheme.core.io.images import read_image, write_image
from terratheme.core.model.project import load_project
from terratheme.core.packing import PackedLayer

BLUE, SAND = (40, 90, 200), (225, 200, 140)


def _halves(h=48, w=64, seed=0, left=BLUE, right=SAND, noise=6.0):
    """Left half ``left``, right half ``right``, with a little noise."""
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 3), np.float64)
    img[:, : w // 2] = left
    img[:, w // 2 :] = right
    return np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)


def _run(args, capsys=None):
    code = main(["convert", *map(str, args)])
    return code


def test_cli_end_to_end_two_half_planes(tmp_path, capsys):
    photo = tmp_path / "photo.png"
    write_image(photo, _halves())
    proj = tmp_path / "out.ttproj"
    assert _run([photo, proj, "--cell", "8"]) == 0
    out = capsys.readouterr().out
    assert "2 themes" in out and "cell 8 x 8" in out
    project = load_project(proj)
    assert project.grid.cell == (8, 8)
    # 64 x 48 photo, cell 8: 9 x 7 vertices; vertex columns 0..3 (x <= 24) blue, 5..8 sand.
    idx = project.grid.indices
    assert idx.shape == (7, 9)
    blue = project.library.index_of(project.metadata["classes"]["1"])
    assert set(idx[:, :4].ravel()) == {idx[0, 0]}
    assert set(idx[:, 5:].ravel()) == {idx[0, 8]}
    assert idx[0, 0] != idx[0, 8]
    assert blue in (idx[0, 0], idx[0, 8])
    assert project.metadata["agreement"] > 0.9
    assert project.photo is not None and project.photo.shape == (48, 64, 3)
    # Preview: the photo's size; its left half is bluish, its right half sandy.
    preview = read_image(tmp_path / "out_preview.png")
    assert preview.shape == (48, 64, 3)
    assert preview[:, :24, 2].mean() > preview[:, :24, 0].mean()
    assert preview[:, 40:, 0].mean() > preview[:, 40:, 2].mean()
    # Packed index layer unpacks to the grid.
    layer = PackedLayer.load(tmp_path / "out.ttpack")
    assert np.array_equal(layer.unpack(indices_only=True).reshape(idx.shape), idx)


def test_cli_auto_cell_and_named_themes(tmp_path):
    photo = tmp_path / "photo.png"
    write_image(photo, _halves(h=96, w=128))
    proj = tmp_path / "p.ttproj"
    prev = tmp_path / "pv.png"
    chart = tmp_path / "curve.png"
    assert _run([photo, proj, "--themes", "sand,water,forest", "--preview", prev,
                 "--packed", tmp_path / "p.pack", "--target-agreement", "0.95",
                 "--curve", chart]) == 0
    project = load_project(proj)
    # Names are matched by colour: the blue class is water, the sandy one sand.
    assert sorted(project.library.names) == ["sand", "water"]
    assert project.library[int(project.grid.indices[0, 0])].name == "water"
    assert project.library[int(project.grid.indices[0, -1])].name == "sand"
    choice = project.metadata["cell_choice"]
    assert choice["target"] == 0.95 and choice["agreement"] >= 0.95
    # Two half planes keep 95% agreement and every class with large cells: the choice is
    # the largest candidate that does (convert tries cells up to 16).
    ok = [p["cell"] for p in choice["curve"] if p["agreement"] >= 0.95
          and p["worst_class_iou"] >= choice["class_target"]]
    assert project.grid.cell == (max(ok), max(ok)) and max(ok) >= 8
    assert max(p["cell"] for p in choice["curve"]) == 16
    assert prev.is_file() and (tmp_path / "p.pack").is_file()
    assert read_image(chart).shape[2] in (3, 4)


def test_flat_photo_gives_one_theme(tmp_path):
    photo = tmp_path / "flat.png"
    write_image(photo, np.full((40, 50, 3), 120, np.uint8))
    proj = tmp_path / "flat.ttproj"
    assert _run([photo, proj]) == 0
    project = load_project(proj)
    assert len(project.library) == 1
    assert set(project.grid.indices.ravel()) == {0}


@pytest.mark.parametrize("size", [1, 3])
def test_tiny_photos(tmp_path, size):
    photo = tmp_path / f"p{size}.png"
    write_image(photo, _halves(h=size, w=size, noise=0))
    proj = tmp_path / f"p{size}.ttproj"
    assert _run([photo, proj]) == 0
    project = load_project(proj)
    assert project.grid.texture_size[0] >= size and project.grid.texture_size[1] >= size
    assert read_image(tmp_path / f"p{size}_preview.png").shape == (size, size, 3)


def test_alpha_and_16_bit(tmp_path):
    rgba = np.dstack([_halves(), np.full((48, 64), 255, np.uint8)])
    rgba[:8, :8, 3] = 0  # a transparent corner: no data
    photo = tmp_path / "alpha.png"
    write_image(photo, rgba)
    assert _run([photo, tmp_path / "a.ttproj", "--cell", "4"]) == 0
    project = load_project(tmp_path / "a.ttproj")
    assert "no data" in project.library.names
    assert project.library[int(project.grid.indices[0, 0])].name == "no data"
    deep = tmp_path / "deep.tif"
    write_image(deep, _halves().astype(np.uint16) * 257)
    assert _run([deep, tmp_path / "d.ttproj", "--cell", "8"]) == 0
    assert len(load_project(tmp_path / "d.ttproj").library) == 2


def test_scribbles(tmp_path):
    photo = tmp_path / "photo.png"
    write_image(photo, _halves())
    mask = np.zeros((48, 64), np.uint8)
    mask[10:12, 4:20] = 1
    mask[30:32, 40:60] = 2
    write_image(tmp_path / "mask.png", mask)
    proj = tmp_path / "s.ttproj"
    assert _run([photo, proj, "--scribbles", tmp_path / "mask.png", "--cell", "8",
                 "--themes", "1=water,2=sand"]) == 0
    project = load_project(proj)
    assert project.library.names == ["water", "sand"]
    assert project.grid.indices[3, 0] == 0 and project.grid.indices[3, 8] == 1
    assert np.array_equal(project.scribbles, mask)


def test_georeference_travels_to_project_and_preview(tmp_path):
    geo = {"ModelPixelScale": [2.0, 2.0, 0.0],
           "ModelTiepoint": [0.0, 0.0, 0.0, 500.0, 900.0, 0.0],
           "GeoKeyDirectory": [1, 1, 0, 1, 3072, 0, 1, 32640]}
    photo = tmp_path / "geo.tif"
    write_georeferenced(photo, _halves(), geo)
    proj = tmp_path / "g.ttproj"
    assert _run([photo, proj, "--cell", "8", "--preview", tmp_path / "g.tif"]) == 0
    assert load_project(proj).metadata["georeference"] == geo
    assert read_georeference(tmp_path / "g.tif") == geo
    assert _run([photo, tmp_path / "h.ttproj", "--cell", "8"]) == 0
    world = (tmp_path / "h_preview.pgw").read_text().split()
    assert [float(v) for v in world] == [2.0, 0.0, 0.0, -2.0, 501.0, 899.0]


def test_user_errors_exit_2(tmp_path, capsys):
    photo = tmp_path / "photo.png"
    write_image(photo, _halves())
    write_image(tmp_path / "small.png", np.zeros((10, 10), np.uint8))
    cases = [
        ([photo, tmp_path / "x.ttproj", "--scribbles", tmp_path / "small.png"], "scribble mask"),
        ([tmp_path / "missing.png", tmp_path / "x.ttproj"], "no such file"),
        ([photo, tmp_path / "x.zip"], "must end in .ttproj"),
        ([photo, tmp_path / "x.ttproj", "--themes", "water,lava"], "unknown theme"),
        ([photo, tmp_path / "x.ttproj", "--themes", "3=water"], "no theme name"),
    ]
    for args, message in cases:
        assert _run(args) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "x.ttproj").exists()
    # Missing output folders are made (the README's `convert ... out/sample.ttproj`).
    assert _run([photo, tmp_path / "new" / "dir" / "x.ttproj", "--cell", "16"]) == 0
    assert (tmp_path / "new" / "dir" / "x_preview.png").is_file()
    with pytest.raises(SystemExit):
        main(["convert", str(photo), "x.ttproj", "--cell", "zero"])


def test_parse_themes():
    assert parse_themes("auto") == "auto"
    assert parse_themes("4") == 4
    assert parse_themes("water, sand") == ["water", "sand"]
    assert parse_themes("1=water,3=town") == {1: "water", 3: "town"}
    assert parse_themes("0003=sand") == {3: "sand"}
    big = "1" * 5000  # past Python's 4300-digit int() limit
    for bad, msg in [("", "empty"), ("0", "1..255"), ("1=water,sand", "mix"),
                     ("x=water", "number"), (big, "1..255"), (f"{big}=water", "number"),
                     (f"1=water,{big}=town", "number"), ("\u00b2", "1..255"),
                     ("\u0661=water", "number"), ("256=town", "number")]:
        with pytest.raises(TerrathemeError, match=msg):
            parse_themes(bad)


def test_convert_photo_progress_and_options():
    seen = []
    res = convert_photo(_halves(), ConvertOptions(cell=8), progress=lambda d, t: seen.append(d))
    assert seen[-1] == 100 and seen == sorted(seen)
    assert res.choice is None and res.labels.shape == (48, 64)
    with pytest.raises(TerrathemeError, match="cell must be"):
        convert_photo(_halves(), ConvertOptions(cell=0))


def test_convert_photo_checks_the_scribbles_before_it_classifies():
    photo = _halves()
    with pytest.raises(TerrathemeError, match="^scribble mask is 10 x 10 pixels but its photo "
                                              "is 64 x 48: a mask must have the photo's size"):
        convert_photo(photo, scribbles=np.zeros((10, 10), np.uint8))
    with pytest.raises(TerrathemeError, match="^scribble mask: values must be integers"):
        convert_photo(photo, scribbles=np.zeros(photo.shape[:2], np.float32))


@pytest.mark.slow
def test_saved_model_whole_and_tiled_paths_agree(tmp_path):
    from terratheme.core.classify import train_classifier

    img = _halves(h=150, w=200)
    photo = tmp_path / "big.tif"
    geo = {"ModelPixelScale": [1.0, 1.0, 0.0], "ModelTiepoint": [0.0, 0.0, 0.0, 10.0, 20.0, 0.0]}
    tifffile.imwrite(photo, img, tile=(32, 32), extratags=tiff_extratags(geo))
    mask = np.zeros((150, 200), np.uint8)
    mask[20:24, 10:80] = 1
    mask[100:104, 120:190] = 2
    train_classifier([(img, mask)]).save(tmp_path / "m.model")
    common = ["--model", tmp_path / "m.model", "--cell", "8", "--themes", "1=water,2=sand"]
    assert _run([photo, tmp_path / "whole.ttproj", *common]) == 0
    assert _run([photo, tmp_path / "tiled.ttproj", *common, "--tile", "64"]) == 0
    whole, tiled = load_project(tmp_path / "whole.ttproj"), load_project(tmp_path / "tiled.ttproj")
    assert whole.library.names == tiled.library.names == ["water", "sand"]
    assert np.array_equal(whole.grid.indices, tiled.grid.indices)
    assert tiled.grid.indices[5, 0] == 0 and tiled.grid.indices[5, -1] == 1
    assert tiled.metadata["georeference"]["ModelTiepoint"][3:5] == [10.0, 20.0]
    assert tiled.photo is None and whole.photo is not None
    assert (tmp_path / "tiled.ttpack").is_file() and (tmp_path / "tiled_preview.png").is_file()
    # Without a model the tiled path is unsupervised (tests/test_convert_tiled_unsupervised.py);
    # with cell auto it chooses on the region's sample (here the whole photo).
    assert _run([photo, tmp_path / "t2.ttproj", "--tile", "64", "--cell", "8"]) == 0
    assert load_project(tmp_path / "t2.ttproj").grid.indices.shape == whole.grid.indices.shape
    assert _run([photo, tmp_path / "t3.ttproj", *common[:2], "--tile", "64"]) == 0
    auto = load_project(tmp_path / "t3.ttproj")
    assert auto.metadata["cell_choice"]["measured_on"] == [[0, 0, 200, 150]]
    assert auto.grid.cell[0] == auto.metadata["cell_choice"]["cell"][0] >= 8


def test_one_class_scribbles_and_float_exr(tmp_path):
    photo = tmp_path / "photo.exr"
    write_image(photo, _halves().astype(np.float32) / 255.0)
    mask = np.zeros((48, 64), np.uint8)
    mask[5:9, 5:30] = 4  # scribbles name one class only
    write_image(tmp_path / "one.png", mask)
    proj = tmp_path / "one.ttproj"
    assert _run([photo, proj, "--scribbles", tmp_path / "one.png", "--cell", "16"]) == 0
    project = load_project(proj)
    # Named after the closest shipped theme (the halves' mean is a sandy grey), never "class 4".
    from terratheme.core.themes.library import shipped_theme_library

    assert len(project.library) == 1
    assert project.library.names[0] in shipped_theme_library().names
    assert set(project.grid.indices.ravel()) == {0}
    # The EXR photo was read as 8-bit RGB for the project.
    assert project.photo.dtype == np.uint8 and project.photo.shape == (48, 64, 3)


def test_reduced_preview_keeps_georeference_scaled(tmp_path):
    from terratheme.core.convert.photo import write_outputs

    geo = {"ModelPixelScale": [1.0, 1.0, 0.0], "ModelTiepoint": [0, 0, 0, 100.0, 200.0, 0]}
    res = convert_photo(_halves(h=40, w=80), ConvertOptions(cell=8),
                        metadata={"georeference": geo})
    out = write_outputs(res.project, tmp_path / "p.ttproj", preview_path=tmp_path / "p.tif",
                        preview_max_side=20)
    assert read_image(out["preview"]).shape == (10, 20, 3)
    got = read_georeference(tmp_path / "p.tif")
    assert got["ModelPixelScale"][:2] == [4.0, 4.0]
    assert got["ModelTiepoint"] == geo["ModelTiepoint"]


def test_cli_colour_map_and_boundary_options(tmp_path):
    from terratheme.core.render.project import project_style

    photo = tmp_path / "h.png"
    write_image(photo, _halves())
    assert _run([photo, tmp_path / "a.ttproj", "--cell", "16"]) == 0
    a = load_project(tmp_path / "a.ttproj")
    assert a.colour_map is not None and project_style(a).boundary is not None
    assert (tmp_path / "a_colour.avif").stat().st_size > 0
    assert _run([photo, tmp_path / "b.ttproj", "--cell", "16", "--colour-map", "off",
                 "--boundary", "linear"]) == 0
    b = load_project(tmp_path / "b.ttproj")
    assert b.colour_map is None and project_style(b).boundary is None
    assert not (tmp_path / "b_colour.avif").exists()


def test_cli_budget_buys_a_finer_colour_map_on_both_paths(tmp_path):
    """--budget sets the bits per photo pixel of grid + map; more bytes, less colour error,
    on the whole photo and tile by tile, within the budget (a grid kept at its label
    agreement may overrun a budget too small for it and the coarsest map)."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(3)
    field = gaussian_filter(rng.normal(0, 1, (320, 384, 3)), (6, 6, 0))
    img = np.clip(128 + 900 * field + rng.normal(0, 8, field.shape), 0, 255).astype(np.uint8)
    img[:, :192] //= 2  # two themes
    photo = tmp_path / "f.png"
    write_image(photo, img)
    for extra in ([], ["--tile", "128"]):
        got = []
        for budget in ("0.08", "0.2", "0.5"):
            proj = tmp_path / f"b{budget}{len(extra)}.ttproj"
            assert _run([photo, proj, "--budget", budget, *extra]) == 0
            meta = load_project(proj).metadata["colour_map"]
            assert meta["budget_bpp"] == float(budget)
            area = texture_cost(load_project(proj)).area_bytes
            assert area <= max(MIN_AREA_BYTES, float(budget) * 320 * 384 / 8)
            got.append((area, meta.get("colour_error")))
        areas = [a for a, _ in got]
        assert areas == sorted(areas) and areas[2] > 4 * areas[0], got
        if not extra:  # the whole photo's map records its colour error (dE8)
            errors = [e for _, e in got]
            assert errors == sorted(errors, reverse=True) and errors[2] < errors[0], got


@pytest.mark.parametrize("args, match", [
    (["--budget", "0.1", "--colour-map", "off"], "does not go with --colour-map off"),
    (["--budget", "0.1", "--colour-map", "2"], "does not go with --colour-map 2"),
    (["--budget", "0"], "--budget must be in (0, 1]"),
    (["--themes", "water,lava"], "unknown theme 'lava'"),
    (["--cell", "16", "--curve", "c.png"], "needs --cell auto"),
    (["--colour-map", "blue"], "not auto or off or a number"),
    (["--class-target", "2"], "must be in"),
])
def test_cli_refuses_before_any_work(tmp_path, capsys, args, match):
    photo = tmp_path / "h.png"
    write_image(photo, _halves())
    code = None
    try:
        code = _run([photo, tmp_path / "x.ttproj", *args])
    except SystemExit as exc:  # argparse errors
        code = exc.code
    assert code == 2
    assert match in capsys.readouterr().err
    assert not (tmp_path / "x.ttproj").exists()


def test_outputs_are_written_as_a_set(tmp_path, monkeypatch):
    import terratheme.core.convert.photo as photo_mod

    photo = tmp_path / "h.png"
    write_image(photo, _halves())
    assert _run([photo, tmp_path / "s.ttproj", "--cell", "16"]) == 0
    names = {"s.ttproj", "s_preview.png", "s.ttpack", "s_colour.avif"}
    before = {n: (tmp_path / n).read_bytes() for n in names}
    # The project (written last) fails: every file of the set keeps its old bytes.
    def fail(path, project):
        raise OSError("disk full")

    monkeypatch.setattr(photo_mod, "save_project", fail)
    write_image(photo, _halves()[:, ::-1].copy())
    assert _run([photo, tmp_path / "s.ttproj", "--cell", "16"]) == 2
    assert {n: (tmp_path / n).read_bytes() for n in names} == before
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert leftovers == []


def test_a_road_theme_keeps_cells_of_at_most_8():
    from terratheme.core.convert.cell_choice import ROAD_MAX_CELL, road_candidates

    assert road_candidates((16, 12, 8, 6, 4), ["sand", "Road"]) == (8, 6, 4)
    assert road_candidates((16, 12, 8), ["sand", "roads"]) == (16, 12, 8)
    assert road_candidates((16, 12), ["road"]) == (16, 12)  # none that small: unchanged
    # Two halves from scribbles: the coarsest cell keeps them; named road, at most 8.
    photo = np.zeros((128, 128, 3), np.uint8)
    photo[:, 64:] = (200, 180, 150)
    mask = np.zeros((128, 128), np.uint8)
    mask[10:20, 5:40] = 1
    mask[10:20, 80:120] = 2
    opts = ConvertOptions(candidates=(32, 16, 8))
    cells = {}
    for first in ("water", "road"):
        made = convert_photo(photo, opts, scribbles=mask, class_names={1: first, 2: "sand"})
        cells[first] = made.project.grid.cell[0]
    assert cells["water"] > ROAD_MAX_CELL and cells["road"] <= ROAD_MAX_CELL
