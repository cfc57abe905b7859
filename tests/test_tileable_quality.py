"""core.themes.quality: low-frequency banding, repetition (ghost) and landmark scores."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.quality import (
    landmark_mask,
    landmark_score,
    lowfreq_score,
    repeat_score,
)


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


def _square(size: int, side: int, y: int, x: int, value: float) -> np.ndarray:
    """A flat grey tile with a ``side``-texel square of ``value`` at (y, x), wrapping."""
    lum = np.full((size, size), 128.0)
    rows = (y + np.arange(side)) % size
    cols = (x + np.arange(side)) % size
    lum[np.ix_(rows, cols)] = value
    return _grey(lum)


def test_landmark_score_by_hand() -> None:
    # A flat tile has no landmark.
    assert landmark_score(np.full((64, 64, 3), 90, np.uint8)) == 0.0
    # A dark 9 x 9 square: found with its blurred rim, about its own area.
    centred = landmark_score(_square(64, 9, 28, 28, 28.0))
    assert 81 / 64**2 <= centred <= 15**2 / 64**2
    # The tile wraps: the same square split over the four corners is one landmark.
    assert landmark_score(_square(64, 9, 60, 60, 28.0)) == pytest.approx(centred)
    # A bright square of the same contrast scores the same (top-hat).
    assert landmark_score(_square(64, 9, 28, 28, 228.0)) == pytest.approx(centred)
    # Too faint to see: under the contrast threshold.
    assert landmark_score(_square(64, 9, 28, 28, 118.0)) == 0.0
    # A stripe across the whole tile runs on into the next tiles: 3 tiles' worth.
    lum = np.full((64, 64), 128.0)
    lum[30:35] = 40.0
    stripe = landmark_score(_grey(lum))
    assert stripe >= 3 * 5 * 64 / 64**2
    dark, bright = landmark_mask(_grey(lum))
    assert dark[30:35].all() and not dark[:20].any() and not bright.any()
    # A stripe along the left edge: a tile wraps it next to bright texels (a landmark);
    # a photo window (not periodic) cannot tell it from the edge of a larger dark area.
    lum = np.full((64, 64), 128.0)
    lum[:, :5] = 40.0
    dark, _ = landmark_mask(_grey(lum))
    assert dark[:, :5].all() and not dark[:, 20:60].any()
    dark, _ = landmark_mask(_grey(lum), periodic=False)
    assert not dark.any()
    lum = np.roll(lum, 12, axis=1)
    dark, _ = landmark_mask(_grey(lum), periodic=False)
    assert dark[:, 12:17].all() and not dark[:, 30:].any()


def test_scores_errors() -> None:
    with pytest.raises(TerrathemeError, match="odd and at least 3"):
        landmark_score(np.zeros((8, 8, 3), np.uint8), size=4)
    for fn in (lowfreq_score, repeat_score, landmark_score):
        with pytest.raises(TerrathemeError, match="too small"):
            fn(np.zeros((3, 8, 3), np.uint8))
        with pytest.raises(TerrathemeError, match="empty"):
            fn(np.zeros((0, 8, 3), np.uint8))


def test_tiles_unseen_rejects_a_tile_that_copies_itself():
    from terratheme.core.themes.quality import REPEAT_LIMIT, tiles_unseen

    rng = np.random.default_rng(4)
    noise = rng.integers(100, 160, (64, 64, 3)).astype(np.uint8)
    repeat, unseen = tiles_unseen(noise)
    assert unseen and repeat < REPEAT_LIMIT
    copies = np.tile(noise[:16, :16], (4, 4, 1))
    repeat, unseen = tiles_unseen(copies)
    assert not unseen and repeat > 0.9
