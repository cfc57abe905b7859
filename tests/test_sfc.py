"""Hilbert and Morton curves: the vector file, an independent reference, scans."""

from __future__ import annotations

import json

import numpy as np
import pytest
import sfc_steps
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.curves import steps as sfc
from terratheme.core.curves.fill import fill_runs
from terratheme.core.curves.scan import ranks_to_steps, scan_runs, steps_to_ranks
from terratheme.core.curves.square import Curve, curve_order
from terratheme.core.errors import TerrathemeError


@pytest.fixture(scope="module")
def vec(shared_vectors):
    return json.loads((shared_vectors / "sfc_8x8.json").read_text())


@pytest.mark.parametrize("curve", ["hilbert", "morton"])
def test_step_tables_match_vector_file(vec, curve):
    expected = np.array(vec[f"{curve}_steps"])
    assert np.array_equal(sfc_steps.step_table(vec["width"], vec["height"], curve), expected)


def _reference_hilbert(n: int) -> list[tuple[int, int]]:
    """Hilbert points (x, y up) by the recursive construction, first move upward."""
    if n == 0:
        return [(0, 0)]
    half = 1 << (n - 1)
    sub = _reference_hilbert(n - 1)
    # Quadrants in order: bottom-left (transposed), top-left, top-right, bottom-right
    # (anti-transposed), so the curve enters at (0, 0) and leaves at (2^n - 1, 0).
    bl = [(y, x) for x, y in sub]
    tl = [(x, y + half) for x, y in sub]
    tr = [(x + half, y + half) for x, y in sub]
    br = [(2 * half - 1 - y, half - 1 - x) for x, y in sub]
    return bl + tl + tr + br


def _reference_morton(x: int, y: int) -> int:
    return sum((((x >> i) & 1) + 2 * ((y >> i) & 1)) << (2 * i) for i in range(17))


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5])
def test_hilbert_matches_recursive_reference(n):
    pts = np.array(_reference_hilbert(n))
    d, _ = sfc.hilbert_xy2d(pts[:, 0], pts[:, 1], n)
    assert np.array_equal(d, np.arange(4**n))
    x, y = sfc.hilbert_d2xy(np.arange(4**n), n)
    assert np.array_equal(np.stack([x, y], 1), pts)


@pytest.mark.parametrize("side", [2, 4, 8, 16, 32, 100])
def test_hilbert_first_move_is_up_and_steps_are_adjacent(side):
    # Image coordinates: step 0 at the bottom-left texel, step 1 just above it, for any size.
    cols, rows, inside = sfc_steps.texels_of(np.arange(side * side), side, side, "hilbert")
    if side == 100:
        cols, rows = cols[inside], rows[inside]
    assert (cols[0], rows[0], cols[1], rows[1]) == (0, side - 1, 0, side - 2)
    if side != 100:
        assert np.all(np.abs(np.diff(cols)) + np.abs(np.diff(rows)) == 1)


@given(st.integers(0, 65535), st.integers(0, 65535))
def test_morton_matches_bit_interleaving(x, y):
    assert int(sfc.morton_xy2d(np.array([x]), np.array([y]), 16)[0]) == _reference_morton(x, y)
    bx, by = sfc.morton_d2xy(np.array([_reference_morton(x, y)]), 16)
    assert (int(bx[0]), int(by[0])) == (x, y)


def test_hilbert_65536_corners():
    # n = 16 is even: the image curve is transposed so that its first move is still up,
    # and its quadrants go bottom-left, bottom-right, top-right, top-left.
    cols = np.array([0, 65535, 65535, 0, 0])
    rows = np.array([65535, 65535, 0, 0, 65534])
    steps = sfc_steps.steps_of(cols, rows, 65536, 65536, "hilbert")
    assert steps[0] == 0 and steps[3] == 2**32 - 1 and steps[4] == 1
    assert 2**30 <= steps[1] < 2**31 and 2**31 <= steps[2] < 3 * 2**30


def _naive_order(w: int, h: int, curve: str) -> np.ndarray:
    steps = sfc_steps.step_table(w, h, curve).ravel()
    return np.argsort(steps, kind="stable")


sizes = st.tuples(st.integers(1, 70), st.integers(1, 70))


@settings(max_examples=40, deadline=None)
@given(sizes, st.sampled_from(["hilbert", "morton"]))
def test_steps_and_texels_invert_each_other(size, curve):
    w, h = size
    rows, cols = np.mgrid[0:h, 0:w]
    steps = sfc_steps.steps_of(cols, rows, w, h, curve)
    c, r, inside = sfc_steps.texels_of(steps, w, h, curve)
    assert inside.all() and np.array_equal(c, cols) and np.array_equal(r, rows)
    n = curve_order(w, h)
    assert steps.max() < 4**n
    assert np.unique(steps).size == w * h


@settings(max_examples=40, deadline=None)
@given(sizes, st.sampled_from(["hilbert", "morton"]), st.integers(1, 4), st.data())
def test_scan_matches_argsort_of_step_table(size, curve, colours, data):
    w, h = size
    order = _naive_order(w, h, curve)
    seed = data.draw(st.integers(0, 2**32 - 1))
    img = np.random.default_rng(seed).integers(0, colours, (h, w)).astype(np.uint8)
    steps_tab = sfc_steps.step_table(w, h, curve, one_based=False).ravel()[order]
    along = img.ravel()[order]
    last = np.append(np.flatnonzero(np.diff(along) != 0), along.size - 1)
    steps, values = scan_runs(img, curve, threads=data.draw(st.integers(1, 3)))
    assert np.array_equal(steps, steps_tab[last])
    assert np.array_equal(values, along[last])
    assert np.array_equal(fill_runs(steps, values, w, h, curve), img)
    assert np.array_equal(steps_to_ranks(steps, w, h, curve), last + 1)
    assert np.array_equal(ranks_to_steps(last + 1, w, h, curve), steps)


@pytest.mark.parametrize("w,h", [(0, 5), (5, 0), (65537, 1), (1, 70000)])
def test_bad_sizes_are_refused(w, h):
    with pytest.raises(TerrathemeError, match="texels"):
        curve_order(w, h)


def test_bad_curve():
    with pytest.raises(TerrathemeError, match="unknown curve"):
        Curve.parse("peano")
