"""core.themes.tileable: making patches tileable, the seam measure, and the shipped themes."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.library import SHIPPED_THEMES_DIR, shipped_theme_library
from terratheme.core.themes.quality import landmark_score, lowfreq_score, repeat_score
from terratheme.core.themes.tileable import (
    SEAM_THRESHOLD,
    TileableOptions,
    flatten_trend,
    make_tileable,
    periodic_component,
    seam_score,
)


def _ramp_patch(seed: int = 0, h: int = 64, w: int = 80) -> np.ndarray:
    """A patch that does not tile: a strong gradient plus noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    base = np.stack([xx * 3, yy * 3, (xx + yy) * 1.5], axis=-1)
    return np.clip(base + rng.normal(0, 6, base.shape), 0, 255).astype(np.uint8)


def _periodic_patch(n: int = 32) -> np.ndarray:
    """Tiles exactly: seeded noise keeping only waves of 5 to 10 periods per tile (FFT)."""
    rng = np.random.default_rng(1)
    k = np.hypot(*np.meshgrid(np.fft.fftfreq(n) * n, np.fft.fftfreq(n) * n))
    spec = np.fft.fft2(rng.standard_normal((n, n))) * ((k >= 5) & (k <= 10))
    base = np.real(np.fft.ifft2(spec))
    base = 128 + 40 * base / base.std()
    return np.clip(np.rint(np.stack([base, base * 0.8, base * 0.5 + 40], -1)), 0, 255).astype(
        np.uint8
    )


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


def test_periodic_input_comes_back_unchanged() -> None:
    patch = _periodic_patch()
    assert seam_score(patch) < 1.2
    out = make_tileable(patch, TileableOptions(flatten=0.0))
    np.testing.assert_array_equal(out, patch)
    # Flattening (sigma 4) passes waves of >= 5 periods per 32 texels almost whole: their
    # blur keeps at most exp(-2 pi^2 16 (5/32)^2) = 0.0004 of them.
    out = make_tileable(patch)
    assert np.abs(out.astype(int) - patch).max() <= 1


@pytest.mark.parametrize("shape", [(64, 80), (20, 36), (4, 4)])
def test_make_tileable_removes_seam_and_keeps_shape(shape) -> None:
    patch = _ramp_patch(h=shape[0], w=shape[1])
    tile = make_tileable(patch)
    assert tile.shape == patch.shape and tile.dtype == np.uint8
    if min(shape) >= 20:
        assert seam_score(patch) > 3 * SEAM_THRESHOLD
        # The wrap edge now steps like the interior next to it.
        assert 0.4 < seam_score(tile) < SEAM_THRESHOLD


def test_periodic_component_by_hand() -> None:
    # A ramp u = 3x along x (n = 16 columns). Moisan: the periodic Laplacian of p equals
    # the free (inside-only) Laplacian of u: +3 at column 0, -3 at column n-1, 0 elsewhere.
    # So p is linear with slope d inside and wrap step w, where d - w = 3 and the steps
    # around the loop sum to 0: (n-1) d + w = 0  ->  d = 3/n, w = -3(n-1)/n.
    n = 16
    ramp = np.broadcast_to((np.arange(n) * 3.0)[None, :, None], (8, n, 3))
    p = periodic_component(ramp)
    np.testing.assert_allclose(np.diff(p, axis=1), 3 / n, atol=1e-4)
    np.testing.assert_allclose(p[:, 0] - p[:, -1], -3 * (n - 1) / n, atol=1e-4)
    np.testing.assert_allclose(np.diff(p, axis=0), 0, atol=1e-4)  # no jump along y
    assert abs(p.mean() - ramp.mean()) < 1e-4  # s has zero mean
    # A constant image has no boundary jump: p = u.
    np.testing.assert_allclose(periodic_component(np.full((5, 7, 3), 9.0)), 9.0, atol=1e-5)


def test_flatten_removes_slow_waves_by_hand() -> None:
    # One cosine period over 64 texels, sigma 16: the periodic Gaussian keeps
    # exp(-2 pi^2 sigma^2 / n^2) = exp(-1.2337) = 0.2912 of it, so flattening leaves
    # 0.7088; a period-4 cosine is kept whole (its blur is exp(-2 pi^2 16) = 0).
    x = np.arange(64)
    slow = 40 * np.cos(2 * np.pi * x / 64)
    fast = 20 * np.cos(2 * np.pi * x / 4)
    img = np.broadcast_to((100 + slow + fast)[None, :, None], (64, 64, 3)).astype(np.float32)
    out = flatten_trend(img, 16.0)[0, :, 0]
    np.testing.assert_allclose(out, 100 + 0.7088 * slow + fast, atol=0.02)


def test_make_tileable_removes_linear_trend() -> None:
    patch = _ramp_patch(seed=4, h=64, w=64)
    out = make_tileable(patch).astype(float)
    # Least-squares slope of the column means, per channel: 3 (red) before.
    for c, before in ((0, 3.0), (2, 1.5)):
        cols = out[:, :, c].mean(axis=0)
        slope = np.polyfit(np.arange(64), cols, 1)[0]
        assert abs(slope) < 0.1 * before
    assert lowfreq_score(out.astype(np.uint8)) < 0.25 < lowfreq_score(patch)


def test_no_ghosts() -> None:
    rng = np.random.default_rng(5)
    patch = np.clip(rng.normal(128, 40, (64, 64, 3)), 0, 255).astype(np.uint8)
    clean = make_tileable(patch, TileableOptions(tiles_already=0))
    # A half-shift cross-fade scores over 0.5 here (it mixes each texel with the one half a
    # tile away); the periodic component copies nothing.
    assert repeat_score(clean) < 0.15


def test_make_tileable_errors() -> None:
    with pytest.raises(TerrathemeError, match="too small"):
        make_tileable(np.zeros((3, 8, 3), np.uint8))
    with pytest.raises(TerrathemeError, match="empty"):
        make_tileable(np.zeros((0, 8, 3), np.uint8))
    patch = np.zeros((8, 8, 3), np.uint8)
    for bad, match in (
        ({"flatten": -0.1}, "flatten"),
        ({"tiles_already": -1.0}, "tiles_already"),
    ):
        with pytest.raises(TerrathemeError, match=match):
            make_tileable(patch, TileableOptions(**bad))


def test_make_tileable_on_dubai_photo(shared_data) -> None:
    from terratheme.core.io.images import read_image

    photo = read_image(shared_data / "dubai" / "images" / "image_part_001t1.jpg", dtype=np.uint8)
    patch = photo[100:228, 100:228, :3]
    tile = make_tileable(patch)
    assert seam_score(tile) < SEAM_THRESHOLD < seam_score(patch)
    assert repeat_score(tile) < repeat_score(patch) + 0.05
    assert lowfreq_score(tile) < 0.5 * lowfreq_score(patch)


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
        # No tile-sized banding: tiled 3 x 3, a dark band or bright corner makes a grid.
        assert lowfreq_score(theme.texture) < 0.2, theme.name
        colours.add(theme.colour)
    assert len(colours) == len(lib)  # display colours tell themes apart
    # Photo themes carry no cross-fade ghosts (the old half-shift fade scored about 0.85).
    for name in ("sand", "town", "grass"):
        assert repeat_score(lib[lib.index_of(name)].texture) < 0.3, name
    # Nor a landmark that repeats once per tile (the first grass had a channel over 5 %
    # of the tile); town keeps its streets.
    for name in ("sand", "grass"):
        assert landmark_score(lib[lib.index_of(name)].texture) < 0.02, name
