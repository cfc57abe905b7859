"""The simulated scribbles of benchmarks/classify_eval.py (one-shot and corrections).

The benchmark helpers are not a package: they are loaded from their file.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "classify_eval.py"


@pytest.fixture(scope="module")
def ev():
    spec = importlib.util.spec_from_file_location("classify_eval_under_test", _PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _inside_class(mask: np.ndarray, strokes: np.ndarray, radius: int = 3) -> bool:
    """Every painted pixel has its class, and so does every pixel within ``radius``.

    Independent of cv2: the 9 x 9 elliptic erosion keeps only pixels whose disc of
    radius 3 lies in the class (borders of the photo count as inside, as in cv2).
    """
    pad = np.pad(mask, radius, mode="edge")
    h, w = mask.shape
    ys, xs = np.nonzero(strokes)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dy * dy + dx * dx > radius * radius:
                continue
            if not np.array_equal(pad[ys + radius + dy, xs + radius + dx], strokes[ys, xs]):
                return False
    return h > 0 and w > 0


def _components(binary: np.ndarray) -> list[set[tuple[int, int]]]:
    """8-connected components by flood fill (independent of cv2)."""
    seen = np.zeros(binary.shape, bool)
    out = []
    for y0, x0 in zip(*np.nonzero(binary), strict=True):
        if seen[y0, x0]:
            continue
        stack, comp = [(y0, x0)], set()
        seen[y0, x0] = True
        while stack:
            y, x = stack.pop()
            comp.add((int(y), int(x)))
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    yy, xx = y + dy, x + dx
                    if (0 <= yy < binary.shape[0] and 0 <= xx < binary.shape[1]
                            and binary[yy, xx] and not seen[yy, xx]):
                        seen[yy, xx] = True
                        stack.append((yy, xx))
        out.append(comp)
    return out


def _halves() -> np.ndarray:
    mask = np.ones((120, 160), np.uint8)
    mask[:, 80:] = 2
    return mask


def test_corrections_hit_the_misclassified_region_with_the_true_class(ev):
    mask = _halves()
    pred = mask.copy()
    pred[30:90, 100:140] = 1  # a 60 x 40 wrong region inside class 2
    pred[10:15, 10:15] = 2  # 25 px wrong: below min_area, not worth a stroke
    wrong = pred != mask
    strokes = ev.simulate_corrections(mask, [1, 2], np.random.default_rng(3), wrong, 400)
    assert 0 < (strokes > 0).sum() <= 400
    # Only the true class of the wrong region, only inside its eroded class region.
    assert set(np.unique(strokes)) == {0, 2}
    assert _inside_class(mask, strokes)
    # Every stroke crosses the wrong region; nothing near the small one.
    for comp in _components(strokes > 0):
        assert any(wrong[y, x] for y, x in comp)
    assert not strokes[:40, :60].any()


def test_corrections_take_the_largest_region_first(ev):
    mask = _halves()
    wrong = np.zeros(mask.shape, bool)
    wrong[20:100, 95:150] = True  # large, class 2
    wrong[40:70, 20:50] = True  # smaller, class 1
    # Paint for one stroke (a whole 30 x 3 cv2 stroke covers 118-172 pixels).
    strokes = ev.simulate_corrections(mask, [1, 2], np.random.default_rng(0), wrong, 200)
    assert (strokes > 0).sum() > 60
    assert set(np.unique(strokes)) == {0, 2}
    # Plenty of paint: both regions get strokes, each of its own true class.
    strokes = ev.simulate_corrections(mask, [1, 2], np.random.default_rng(0), wrong, 2000)
    assert (strokes[:, :80] == 1).any() and (strokes[:, 80:] == 2).any()
    assert set(np.unique(strokes)) == {0, 1, 2}


def test_corrections_leave_existing_strokes_and_ignored_classes(ev):
    mask = _halves()
    mask[:, 140:] = 7  # a class the user never paints (e.g. ignored)
    existing = np.zeros_like(mask)
    existing[50:70, 100:130] = 2
    wrong = np.ones(mask.shape, bool)
    strokes = ev.simulate_corrections(mask, [1, 2], np.random.default_rng(1), wrong, 3000,
                                      existing=existing)
    # It paints (most of the budget), around the strokes already there.
    assert (strokes > 0).sum() > 1500
    assert not (strokes[existing > 0]).any()
    assert not (strokes == 7).any() and not strokes[:, 136:].any()
    assert _inside_class(mask, strokes)


def test_no_target_no_strokes(ev):
    mask = _halves()
    strokes = ev.simulate_corrections(mask, [1, 2], np.random.default_rng(0),
                                      np.zeros(mask.shape, bool), 1000)
    assert strokes.shape == mask.shape and not strokes.any()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), budget=st.floats(0.001, 0.02))
def test_two_rounds_respect_the_budget_and_the_classes(ev, seed, budget):
    rng = np.random.default_rng(seed)
    # Blocky truth (6 x 8 cells of 20 px, classes 1..3) and a blocky wrong map.
    mask = np.kron(rng.integers(1, 4, (6, 8)), np.ones((20, 20), np.int64)).astype(np.uint8)
    wrong = np.kron(rng.random((12, 16)) < 0.3, np.ones((10, 10), bool))
    total = int(budget * mask.size)
    first = ev.simulate_scribbles(mask, [1, 2, 3], rng, budget=budget / 2)
    second = ev.simulate_corrections(mask, [1, 2, 3], rng, wrong,
                                     total - int((first > 0).sum()), existing=first)
    # A class's share of the first half holds a whole stroke (at most 30 x 3 + caps): painted.
    if budget / 2 * mask.size / 3 >= 130:
        assert (first > 0).any()
    assert not (first.astype(bool) & second.astype(bool)).any()
    assert int((first > 0).sum() + (second > 0).sum()) <= total
    assert _inside_class(mask, first) and _inside_class(mask, second)
