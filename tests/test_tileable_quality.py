"""core.tile_quality: low-frequency banding and repetition (ghost) scores."""

from __future__ import annotations

import numpy as np
import pytest

from core.errors import TerrathemeError
from core.tile_quality import lowfreq_score, repeat_score


def _grey(lum: np.ndarray) -> np.ndarray:
    return np.repeat(np.clip(np.rint(lum), 0, 255).astype(np.uint8)[..., None], 3, axis=2)


def test_lowfreq_score_by_hand() -> None:
    x = np.arange(64)
    # One period per tile: all the contrast is in the lowest wave -> 1.
    one = _grey(np.broadcast_to(128 + 60 * np.cos(2 * np.pi * x / 64), (64, 64)))
    assert lowfreq_score(one) == pytest.approx(1.0, abs=0.01)
    # Sixteen periods per tile: none of it -> 0.
    fast = _grey(np.broadcast_to(128 + 60 * np.cos(2 * np.pi * x / 4), (64, 64)))
    assert lowfreq_score(fast) == pytest.approx(0.0, abs=0.01)
    # Both, equal amplitude: half the power is slow -> sqrt(1/2).
    both = np.broadcast_to(
        128 + 50 * np.cos(2 * np.pi * x / 64) + 50 * np.cos(2 * np.pi * x / 4), (64, 64)
    )
    assert lowfreq_score(_grey(both)) == pytest.approx(np.sqrt(0.5), abs=0.02)
    assert lowfreq_score(np.full((8, 8, 3), 50, np.uint8)) == 0.0


def test_repeat_score_by_hand() -> None:
    rng = np.random.default_rng(0)
    noise = rng.normal(128, 40, (64, 64))
    # Independent noise: correlations at other shifts are about 1/64 each.
    assert repeat_score(_grey(noise)) < 0.15
    # Left half copied to the right half: correlation 1 at a shift of half a tile.
    half = np.tile(noise[:, :32], (1, 2))
    assert repeat_score(_grey(half)) == pytest.approx(1.0, abs=0.02)
    # A ghost over the whole tile: the patch averaged with its half-shifted copy is
    # g(x) = (a(x) + a(x + 32)) / 2 = g(x + 32): correlation 1 at that shift.
    ghost = 0.5 * (noise + np.roll(noise, 32, axis=1))
    assert repeat_score(_grey(ghost)) == pytest.approx(1.0, abs=0.05)
    # A ghost over a quarter of the tile: columns 0-15 are (a_x + a_{x+32}) / 2. At shift 32,
    # columns 0-15 and 32-47 each give 0.5 var per column: 32 * 0.5 = 16; the total power
    # is 48 * 1 + 16 * 0.5 = 56 (var per column): correlation 16 / 56 = 0.286.
    quarter = noise.copy()
    quarter[:, :16] = 0.5 * (noise[:, :16] + noise[:, 32:48])
    assert repeat_score(_grey(quarter)) == pytest.approx(16 / 56, abs=0.06)
    assert repeat_score(np.full((8, 8, 3), 9, np.uint8)) == 0.0


def test_scores_errors() -> None:
    for fn in (lowfreq_score, repeat_score):
        with pytest.raises(TerrathemeError, match="too small"):
            fn(np.zeros((3, 8, 3), np.uint8))
        with pytest.raises(TerrathemeError, match="empty"):
            fn(np.zeros((0, 8, 3), np.uint8))
