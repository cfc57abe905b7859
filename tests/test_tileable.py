"""core.tileable: making patches tileable, the seam measure, and the shipped themes."""

from __future__ import annotations

import numpy as np
import pytest

from core.errors import TerrathemeError
from core.themes import SHIPPED_THEMES_DIR, shipped_theme_library
from core.tileable import SEAM_THRESHOLD, TileableOptions, make_tileable, seam_score


def _ramp_patch(seed: int = 0) -> np.ndarray:
    """A patch that does not tile: a strong gradient plus noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:64, 0:80]
    base = np.stack([xx * 3, yy * 3, (xx + yy) * 1.5], axis=-1)
    return np.clip(base + rng.normal(0, 6, base.shape), 0, 255).astype(np.uint8)


def test_seam_score_by_hand() -> None:
    # Columns 0, 10, 20, 30: interior steps 10, wrap step |0 - 30| = 30 -> score 3.
    t = np.zeros((4, 4, 3), dtype=np.uint8)
    t[:, :, :] = np.array([0, 10, 20, 30], dtype=np.uint8)[None, :, None]
    assert seam_score(t) == pytest.approx(3.0)
    # Rows vary too: the larger axis wins.
    t2 = t.copy()
    t2[:, :, :] += np.array([0, 5, 10, 60], dtype=np.uint8)[:, None, None]
    # rows: interior steps 5, 5, 50 (mean 20), wrap 60 -> 3; columns unchanged -> 3
    assert seam_score(t2) == pytest.approx(3.0)
    # Tiling a tileable texture: a periodic sine scores about 1.
    x = np.arange(32)
    sine = (127 + 100 * np.sin(2 * np.pi * x / 32)).astype(np.uint8)
    assert seam_score(np.broadcast_to(sine[None, :, None], (32, 32, 3)).copy()) < 1.1


def test_seam_score_flat_and_errors() -> None:
    assert seam_score(np.full((8, 8, 3), 7, np.uint8)) == 0.0
    with pytest.raises(TerrathemeError, match="too small"):
        seam_score(np.zeros((2, 8, 3), np.uint8))
    with pytest.raises(TerrathemeError, match="RGB"):
        seam_score(np.zeros((8, 8), np.uint8))


@pytest.mark.parametrize("histogram", [True, False])
def test_make_tileable_removes_seam(histogram: bool) -> None:
    patch = _ramp_patch()
    assert seam_score(patch) > 3 * SEAM_THRESHOLD
    tile = make_tileable(patch, TileableOptions(histogram=histogram))
    assert tile.shape == patch.shape and tile.dtype == np.uint8
    assert seam_score(tile) < SEAM_THRESHOLD
    # The centre keeps the original texels (weight 1 there).
    np.testing.assert_allclose(tile[28:36, 36:44].astype(int), patch[28:36, 36:44], atol=1)


def test_make_tileable_histogram_keeps_contrast() -> None:
    rng = np.random.default_rng(3)
    patch = rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)
    lin = make_tileable(patch, TileableOptions(histogram=False))
    his = make_tileable(patch, TileableOptions(histogram=True))
    # Plain averaging of independent noise lowers its spread; the histogram blend does not.
    assert his.std() > lin.std() + 5
    assert abs(his.std() - patch.std()) < 4


def test_make_tileable_errors() -> None:
    with pytest.raises(TerrathemeError, match="too small"):
        make_tileable(np.zeros((3, 8, 3), np.uint8))
    with pytest.raises(TerrathemeError, match="band"):
        make_tileable(np.zeros((8, 8, 3), np.uint8), TileableOptions(band=0.0))
    with pytest.raises(TerrathemeError, match="empty"):
        make_tileable(np.zeros((0, 8, 3), np.uint8))


def test_make_tileable_on_dubai_photo(shared_data) -> None:
    from core.image_io import read_image

    photo = read_image(shared_data / "dubai" / "images" / "image_part_001t1.jpg", dtype=np.uint8)
    patch = photo[100:228, 100:228, :3]
    assert seam_score(make_tileable(patch)) < SEAM_THRESHOLD < seam_score(patch)


def test_shipped_themes_pass_seam_test() -> None:
    lib = shipped_theme_library()
    assert len(lib) >= 8
    need = {"forest", "grass", "crop field", "water", "sand", "rock", "town", "road"}
    assert need <= set(lib.names)
    total = sum(p.stat().st_size for p in SHIPPED_THEMES_DIR.glob("*.png"))
    assert total < 2_000_000
    colours = set()
    for theme in lib:
        assert theme.texture.shape[0] >= 64 and theme.texture.shape[1] >= 64
        assert seam_score(theme.texture) < SEAM_THRESHOLD, theme.name
        colours.add(theme.colour)
    assert len(colours) == len(lib)  # display colours tell themes apart
