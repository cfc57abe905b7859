"""core.themes.detail: a theme's fine detail around its mean colour."""

from __future__ import annotations

import numpy as np
from terratheme.core.themes.detail import detail_library, detail_texture
from terratheme.core.themes.library import Theme, ThemeLibrary


def test_detail_of_a_flat_texture_is_the_texture():
    flat = np.full((16, 16, 3), (10, 120, 250), np.uint8)
    assert np.array_equal(detail_texture(flat), flat)


def test_detail_drops_a_slow_ramp_and_keeps_a_checkerboard_and_the_mean():
    yy, xx = np.indices((64, 64))
    # One period of a cosine across the tile: coarse, tileable; a 1-texel checkerboard: fine.
    ramp = 128 + 60 * np.cos(2 * np.pi * xx / 64)
    board = 20 * ((xx + yy) % 2 * 2 - 1)
    tex = np.repeat((ramp + board)[:, :, None], 3, axis=2).round().astype(np.uint8)
    out = detail_texture(tex, sigma=3.0).astype(float)
    # The ramp's 120 grey levels swing is gone but for 4% (a sigma-3 blur keeps
    # exp(-2 pi^2 3^2 / 64^2) = 96% of a 64-texel cosine) ...
    col_means = out.mean(axis=0)[:, 0]
    assert np.ptp(col_means) < 8.0
    # ... the checkerboard stays (a sigma-3 blur removes it, so the high-pass keeps it whole) ...
    assert abs(np.abs(out[:, :, 0] - out[:, :, 0].mean()).mean() - 20) < 1.5
    # ... and the mean colour too.
    assert abs(out.mean() - tex.mean()) < 0.5


def test_detail_texture_stays_tileable():
    rng = np.random.default_rng(0)
    tex = rng.integers(0, 256, (32, 32, 3), dtype=np.uint8)
    # Rolling then filtering equals filtering then rolling: the blur wraps around.
    assert np.array_equal(detail_texture(np.roll(tex, 5, axis=1)),
                          np.roll(detail_texture(tex), 5, axis=1))


def test_detail_library_keeps_names_and_colours():
    tex = np.zeros((8, 8, 3), np.uint8)
    tex[::2] = 200
    lib = ThemeLibrary([Theme("sand", (200, 180, 150), tex)])
    out = detail_library(lib)
    assert out.names == ["sand"] and out[0].colour == (200, 180, 150)
    assert np.array_equal(out[0].texture, detail_texture(tex))
