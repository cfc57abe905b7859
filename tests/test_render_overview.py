"""Overview renders, render_project, the sample maps and the render/new CLI."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import read_image, write_image
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.index_image import indices_from_image
from terratheme.core.model.project import ThematicTexture, load_project
from terratheme.core.render.overview import render_overview
from terratheme.core.render.project import render_project
from terratheme.core.render.renderer import render_cells
from terratheme.core.themes.library import Theme, ThemeLibrary, shipped_theme_library

SAMPLES = Path(__file__).resolve().parents[1] / "sample_maps"


def _project(seed: int = 0) -> ThematicTexture:
    rng = np.random.default_rng(seed)
    lib = ThemeLibrary(
        Theme(f"t{k}", (k * 40, 0, 0),
              (rng.integers(0, 70, (24, 20, 3)) + [60 * k, 180 - 60 * k, 90]).astype(np.uint8))
        for k in range(4)
    )
    return ThematicTexture(IndexGrid(rng.integers(0, 4, (13, 17)), (16, 12)), lib)


@pytest.mark.parametrize("scale", [0.5, 0.25, 1 / 8, 1 / 30])
def test_overview_close_to_downscaled_full_render(scale: float) -> None:
    p = _project()
    full = render_project(p)
    ov = render_project(p, scale=scale)
    h, w = full.shape[:2]
    assert ov.shape == (max(1, round(h * scale)), max(1, round(w * scale)), 3)
    ref = cv2.resize(full, (ov.shape[1], ov.shape[0]), interpolation=cv2.INTER_AREA)
    diff = np.abs(ov.astype(int) - ref)
    assert diff.mean() < 6.0
    # Against a mismatched reference (shifted by a quarter of the image) it is far worse.
    assert np.abs(np.roll(ov, ov.shape[1] // 4, axis=1).astype(int) - ref).mean() > 2 * diff.mean()


def test_overview_region_and_uniform_exact_mean() -> None:
    p = _project(1)
    full = render_project(p)
    ov = render_project(p, (32, 24, 128, 96), scale=0.25)
    assert ov.shape == (24, 32, 3)
    ref = cv2.resize(full[24:120, 32:160], (32, 24), interpolation=cv2.INTER_AREA)
    assert np.abs(ov.astype(int) - ref).mean() < 6.0
    # A uniform grid far zoomed out: every pixel is the theme's mean colour.
    t = p.library[2].texture
    ov = render_overview(np.full((5, 5), 2), p.library.textures, (48, 48), scale=1 / 96)
    np.testing.assert_allclose(ov[0, 0], t.reshape(-1, 3).mean(axis=0), atol=0.51)


def test_render_project_errors() -> None:
    p = _project()
    with pytest.raises(TerrathemeError, match="scale"):
        render_project(p, scale=0)
    with pytest.raises(TerrathemeError, match="scale"):
        render_project(p, scale=2.0)
    with pytest.raises(TerrathemeError, match="outside"):
        render_project(p, (0, 0, 10_000, 10), scale=0.5)


def test_indices_from_colour_image() -> None:
    lib = shipped_theme_library().select(["water", "sand", "forest"])
    img = np.zeros((3, 4, 3), np.uint8)
    img[:] = lib.colours[1]
    img[0, 0] = lib.colours[0]
    img[2, 3] = lib.colours[2] + 3  # a lossy save moved it a little
    idx = indices_from_image(img, lib)
    assert idx[0, 0] == 0 and idx[1, 1] == 1 and idx[2, 3] == 2
    img[1, 2] = (255, 0, 255)
    with pytest.raises(TerrathemeError, match=r"\(255, 0, 255\) at x=2 y=1"):
        indices_from_image(img, lib)
    with pytest.raises(TerrathemeError, match="only 3 themes"):
        indices_from_image(np.full((3, 3), 5, np.uint8), lib)


@pytest.mark.parametrize("name", ["coastline", "river_valley", "airfield"])
def test_sample_maps_render(name: str) -> None:
    p = load_project(SAMPLES / f"{name}.ttproj")
    img = read_image(SAMPLES / f"{name}.png")
    np.testing.assert_array_equal(p.grid.indices, img[:, :, 0])
    assert len(np.unique(p.grid.indices)) >= 4
    view = render_project(p, (200, 100, 300, 200))
    assert view.shape == (200, 300, 3) and view.std() > 5
    np.testing.assert_array_equal(
        view, render_cells(p.grid.indices, p.library.textures, p.grid.cell)[100:300, 200:500]
    )


def test_cli_new_and_render(tmp_path, capsys) -> None:
    lib = shipped_theme_library().select(["water", "sand", "forest"])
    idx = np.array([[0, 0, 1, 2], [0, 1, 1, 2], [0, 1, 2, 2]], np.uint8)
    write_image(tmp_path / "grey.png", idx[:, :, None])
    write_image(tmp_path / "colour.png", lib.colours[idx])
    for src in ("grey.png", "colour.png"):
        proj = tmp_path / f"{src}.ttproj"
        assert main(["new", str(tmp_path / src), str(proj), "--themes", "water,sand,forest",
                     "--cell", "8x6"]) == 0
        p = load_project(proj)
        np.testing.assert_array_equal(p.grid.indices, idx)
        assert p.grid.cell == (8, 6) and p.library.names == ["water", "sand", "forest"]
    out = tmp_path / "full.png"
    assert main(["render", str(proj), str(out)]) == 0
    full = read_image(out)
    np.testing.assert_array_equal(full, render_project(p))
    assert main(["render", str(proj), str(tmp_path / "r.png"), "--region", "3,2,10,7",
                 "--blend", "histogram"]) == 0
    assert read_image(tmp_path / "r.png").shape == (7, 10, 3)
    assert main(["render", str(proj), str(tmp_path / "s.png"), "--scale", "0.5"]) == 0
    assert read_image(tmp_path / "s.png").shape == (6, 12, 3)
    capsys.readouterr()
    assert main(["new", str(tmp_path / "grey.png"), str(tmp_path / "x.ttproj"),
                 "--themes", "water,lava"]) == 2
    assert "unknown theme 'lava'" in capsys.readouterr().err
    assert main(["render", str(proj), str(tmp_path / "y.png"), "--region", "0,0,999,9"]) == 2
    assert "outside" in capsys.readouterr().err
    assert main(["render", str(tmp_path / "none.ttproj"), str(tmp_path / "y.png")]) == 2
    assert not (tmp_path / "y.png").exists()


def test_overview_follows_shaped_borders():
    import cv2
    from terratheme.core.render.boundary import BoundaryOptions
    from terratheme.core.render.renderer import RenderOptions

    rng = np.random.default_rng(0)
    grid = rng.integers(0, 3, (20, 24)).astype(np.uint8)
    themes = [rng.integers(0, 256, (16, 16, 3), dtype=np.uint8) // 2 + 60 * k for k in range(3)]
    shaped = BoundaryOptions()
    full = render_cells(grid, themes, (16, 16), options=RenderOptions(boundary=shaped))
    for scale in (0.5, 0.25):
        ov = render_overview(grid, themes, (16, 16), scale=scale, boundary=shaped)
        area = cv2.resize(full.astype(np.float32), ov.shape[1::-1], interpolation=cv2.INTER_AREA)
        plain = render_overview(grid, themes, (16, 16), scale=scale)
        err = np.abs(ov - area).mean()
        # Within a few levels of the area-averaged full render, far closer than the ramp's.
        assert err < 4.0 and err < 0.4 * np.abs(plain - area).mean()
