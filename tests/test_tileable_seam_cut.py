"""core.themes.seam_cut: minimum-error boundary cuts (Efros & Freeman 2001) across a wrap edge."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.themes.seam_cut import cut_wrap, min_error_cut


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


def test_cut_wrap_edges_come_from_the_shifted_copy() -> None:
    rng = np.random.default_rng(2)
    img = rng.random((16, 32, 3)).astype(np.float32) * 255
    out = cut_wrap(img, 1, overlap=0.125, feather=0)
    # Hard cut: the two columns at the wrap edge are the half-shifted copy's, which are
    # neighbours in the patch (columns 15 and 16), so the wrap is seamless.
    np.testing.assert_array_equal(out[:, -1], img[:, 15])
    np.testing.assert_array_equal(out[:, 0], img[:, 16])
    # Away from the 4-column band on each side, the patch is untouched.
    np.testing.assert_array_equal(out[:, 5:27], img[:, 5:27])
    # Every texel is one source's or the other's: no averaging (no ghosts).
    shifted = np.roll(img, -16, axis=1)
    assert np.all((out == img) | (out == shifted))
    # Rows: the same along axis 0.
    out0 = cut_wrap(img, 0, overlap=0.125, feather=0)
    np.testing.assert_array_equal(out0[-1], img[7])
    np.testing.assert_array_equal(out0[0], img[8])


def test_cut_wrap_keeps_a_half_periodic_patch() -> None:
    # Period 8 along x in a 32-wide patch: the shifted copy equals the patch, error 0.
    rng = np.random.default_rng(3)
    img = np.tile(rng.random((12, 8, 3)).astype(np.float32), (1, 4, 1))
    np.testing.assert_allclose(cut_wrap(img, 1, overlap=0.25, feather=2), img, atol=1e-5)


def test_cut_wrap_feather_and_tiny() -> None:
    img = np.random.default_rng(4).random((4, 4, 3)).astype(np.float32)
    out = cut_wrap(img, 1, overlap=0.25, feather=3)  # feather clamped to the 1-texel band
    assert out.shape == img.shape and out.dtype == np.float32
    np.testing.assert_array_equal(out[:, -1], img[:, 1])
    np.testing.assert_array_equal(out[:, 0], img[:, 2])
