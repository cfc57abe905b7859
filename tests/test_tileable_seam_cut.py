"""core.themes.seam_cut: minimum-error boundary cuts (Efros & Freeman 2001)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.themes.seam_cut import min_error_cut


def test_min_error_cut_follows_the_free_path() -> None:
    # Cost 1 everywhere except a zero-cost 8-connected path drawn by hand.
    free = [2, 3, 3, 4, 3, 2, 1, 1]
    err = np.ones((8, 6))
    err[np.arange(8), free] = 0.0
    np.testing.assert_array_equal(min_error_cut(err), free)


def test_min_error_cut_cyclic_closes_up() -> None:
    # Free path from column 0 (top) to column 5 (bottom): cheap, but it does not close up.
    err = np.ones((10, 6))
    err[np.arange(10), [0, 1, 2, 3, 4, 5, 5, 5, 5, 5]] = 0.0
    open_path = min_error_cut(err)
    assert open_path[0] == 0 and open_path[-1] == 5
    closed = min_error_cut(err, cyclic=True)
    assert abs(int(closed[-1]) - int(closed[0])) <= 1
    assert np.all(np.abs(np.diff(closed)) <= 1)


@settings(max_examples=40, deadline=None)
@given(h=st.integers(1, 12), k=st.integers(1, 7), seed=st.integers(0, 10_000), cyc=st.booleans())
def test_min_error_cut_is_optimal(h: int, k: int, seed: int, cyc: bool) -> None:
    err = np.random.default_rng(seed).random((h, k))
    path = min_error_cut(err, cyclic=cyc)
    assert path.shape == (h,) and path.min() >= 0 and path.max() < k
    assert np.all(np.abs(np.diff(path)) <= 1)
    if not cyc and h <= 6 and k <= 4:
        # Brute force over every 8-connected path (independent of the DP).
        best = np.inf
        for code in range(k**h):
            p = [(code // k**i) % k for i in range(h)]
            if all(abs(a - b) <= 1 for a, b in zip(p, p[1:], strict=False)):
                best = min(best, err[np.arange(h), p].sum())
        assert err[np.arange(h), path].sum() == pytest.approx(best)

