"""``terratheme convert BIG --tile N`` without a model: unsupervised themes, tile by tile."""

from __future__ import annotations

import numpy as np
import pytest
import terratheme.core.convert.tiled as ct
from terratheme.app.cli import main
from terratheme.core.convert.tiled import convert_file_tiled, sample_pieces
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import write_image
from terratheme.core.model.project import load_project

GREEN, SAND, BLUE = (40, 120, 40), (225, 200, 140), (40, 90, 200)


def quadrants(h=192, w=256, seed=1):
    """Green left half; right half sand above, blue below; a little noise."""
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 3), np.float64)
    img[:, : w // 2] = GREEN
    img[: h // 2, w // 2 :] = SAND
    img[h // 2 :, w // 2 :] = BLUE
    return np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)


def _run(args):
    return main(["convert", *map(str, args)])


def test_tiled_unsupervised_equals_whole_image(tmp_path):
    img = quadrants()
    photo = tmp_path / "big.tif"
    write_image(photo, img, tile=32)
    assert _run([photo, tmp_path / "whole.ttproj", "--cell", "8"]) == 0
    assert _run([photo, tmp_path / "tiled.ttproj", "--cell", "8", "--tile", "64"]) == 0
    whole, tiled = load_project(tmp_path / "whole.ttproj"), load_project(tmp_path / "tiled.ttproj")
    assert len(tiled.library) == len(whole.library) == 3
    a, b = whole.grid.indices, tiled.grid.indices
    assert a.shape == b.shape == (192 // 8 + 1, 256 // 8 + 1)
    assert (a == b).mean() > 0.99
    # Labels consistent across tiles: each quadrant's interior is one index, three distinct.
    g, s, bl = b[2:-2, 2:14], b[2:10, 18:-2], b[14:-2, 18:-2]
    assert len(np.unique(g)) == len(np.unique(s)) == len(np.unique(bl)) == 1
    assert len({g[0, 0], s[0, 0], bl[0, 0]}) == 3


def test_big_photo_is_fitted_on_spread_windows(tmp_path, monkeypatch):
    img = quadrants()
    photo = tmp_path / "big.tif"
    write_image(photo, img, tile=32)
    # Whole photo under the budget; 4 x 4 windows of 96 / 4 = 24 px over it.
    assert [p.shape for p in sample_pieces(photo)] == [(192, 256, 3)]
    pieces = sample_pieces(photo, budget=96)
    assert len(pieces) == 16 and all(p.shape == (24, 24, 3) for p in pieces)
    # Window (gx=0, gy=0) is centred at (32, 24): x0 = 32 - 12, y0 = 24 - 12.
    assert (pieces[0] == img[12:36, 20:44]).all()
    assert (pieces[15] == img[156:180, 212:236]).all()
    # With a small budget the windows still hold all three themes.
    monkeypatch.setattr(ct, "THEME_WINDOW", 96)
    proj = convert_file_tiled(photo, None, 8, tile=64)
    assert len(proj.library) == 3
    assert proj.metadata["created_by"] == "terratheme convert (tiled)"


def test_fixed_theme_count_and_names(tmp_path):
    photo = tmp_path / "big.tif"
    write_image(photo, quadrants(), tile=32)
    two = convert_file_tiled(photo, None, 8, themes=2, tile=64)
    assert len(two.library) == 2
    named = convert_file_tiled(photo, None, 8, names=["water", "sand", "grass"], tile=64)
    assert sorted(named.library.names) == ["grass", "sand", "water"]
    # Each quadrant got the theme nearest its colour.
    idx = named.grid.indices
    names = named.library.names
    assert names[idx[5, 5]] == "grass" and names[idx[5, -5]] == "sand"
    assert names[idx[-5, -5]] == "water"
    with pytest.raises(TerrathemeError, match="only 2 names"):
        convert_file_tiled(photo, None, 8, themes=3, names=["water", "sand"], tile=64)
    with pytest.raises(TerrathemeError, match="assigned by colour"):
        convert_file_tiled(photo, None, 8, names={1: "water"}, tile=64)


def test_tiled_cli_errors(tmp_path, capsys):
    photo = tmp_path / "big.tif"
    write_image(photo, quadrants(h=64, w=64), tile=32)
    mask = tmp_path / "m.png"
    write_image(mask, np.ones((64, 64), np.uint8))
    out = tmp_path / "o.ttproj"
    assert _run([photo, out, "--tile", "64", "--scribbles", mask]) == 2
    assert "--tile does not take --scribbles" in capsys.readouterr().err
    assert _run([photo, out, "--tile", "8"]) == 2
    assert "must be >= 16" in capsys.readouterr().err
    assert _run([photo, out, "--tile", "32", "--themes", "2", "--cell", "8"]) == 0
    assert len(load_project(out).library) == 2


def test_trained_model_refuses_theme_count_and_position_features(tmp_path):
    from terratheme.core.classify import FeatureOptions, SupervisedOptions, train_classifier

    img = quadrants(h=64, w=64)
    photo = tmp_path / "big.tif"
    write_image(photo, img, tile=32)
    mask = np.zeros((64, 64), np.uint8)
    mask[10:13, 5:20], mask[10:13, 40:60] = 1, 2
    model = train_classifier([(img, mask)])
    with pytest.raises(TerrathemeError, match="themes K is for unsupervised"):
        convert_file_tiled(photo, model, 8, themes=3, tile=32)
    placed = train_classifier([(img, mask)],
                              SupervisedOptions(features=FeatureOptions(position=True)))
    with pytest.raises(TerrathemeError, match="pixel positions"):
        convert_file_tiled(photo, placed, 8, tile=32)
    model.save(tmp_path / "m.model")
    out = tmp_path / "o.ttproj"
    assert _run([photo, out, "--tile", "32", "--model", tmp_path / "m.model",
                 "--themes", "3"]) == 2
