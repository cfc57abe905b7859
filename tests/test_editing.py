"""Painting the grid in the core edit document (core.edit.document, atoms, tools): no Qt."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.edit import (
    EditAtom,
    EditDocument,
    GridChange,
    MultiAtom,
    Step,
    dirty_cells,
    dirty_region,
)
from terratheme.core.edit.tools import (
    capsule_footprint,
    flood_footprint,
    rect_footprint,
)
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.themes.library import ThemeLibrary, flat_theme


def make_texture(indices: np.ndarray, cell=(4, 4), k: int = 4) -> ThematicTexture:
    """A texture over ``indices`` with ``k`` flat themes."""
    lib = ThemeLibrary(flat_theme(f"t{i}", (40 * i, 255 - 40 * i, 7 * i)) for i in range(k))
    return ThematicTexture(IndexGrid(indices, cell), lib)


def the_atom(step: Step):
    """The one paint a grid edit step holds."""
    assert step is not None and len(step.changes) == 1
    return step.changes[0].atom


def brute_capsule(shape, p0, p1, r):
    """Independent reference: loop over vertices, distance to segment by formula."""
    out = np.zeros(shape, dtype=bool)
    (ax, ay), (bx, by) = p0, p1
    for j in range(shape[0]):
        for i in range(shape[1]):
            dx, dy = bx - ax, by - ay
            l2 = dx * dx + dy * dy
            t = 0.0 if l2 == 0 else max(0.0, min(1.0, ((i - ax) * dx + (j - ay) * dy) / l2))
            d = math.hypot(i - (ax + t * dx), j - (ay + t * dy))
            if d <= r + 1e-9:
                out[j, i] = True
    for px, py in (p0, p1):
        ci, ri = math.floor(px + 0.5), math.floor(py + 0.5)
        if 0 <= ri < shape[0] and 0 <= ci < shape[1]:
            out[ri, ci] = True
    return out


def full_mask(sel, shape: tuple[int, int]) -> np.ndarray:
    """A VertexSelection as a whole-grid ``shape`` bool mask."""
    out = np.zeros(shape, dtype=bool)
    out[sel.rows, sel.cols] = sel.mask
    return out


def test_single_dab_is_a_disc():
    fp = capsule_footprint((9, 9), (4, 4), (4, 4), 2.0)
    got = full_mask(fp, (9, 9))
    # Vertices with dx^2 + dy^2 <= 4 around (4, 4): 13 of them, listed by hand.
    expected = np.zeros((9, 9), dtype=bool)
    for dx, dy in [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1),
                   (-1, -1), (2, 0), (-2, 0), (0, 2), (0, -2)]:
        expected[4 + dy, 4 + dx] = True
    np.testing.assert_array_equal(got, expected)


@settings(max_examples=60, deadline=None)
@given(
    st.tuples(st.floats(-3, 20), st.floats(-3, 15)),
    st.tuples(st.floats(-3, 20), st.floats(-3, 15)),
    st.floats(0, 4),
)
def test_capsule_matches_brute_force(p0, p1, r):
    shape = (13, 18)
    got = full_mask(capsule_footprint(shape, p0, p1, r), shape)
    np.testing.assert_array_equal(got, brute_capsule(shape, p0, p1, r))


def test_brush_stroke_changes_exactly_the_vertices_under_it():
    base = np.zeros((20, 30), dtype=np.uint8)
    base[:, 20:] = 2
    tex = make_texture(base.copy())
    s = EditDocument(tex)
    pts = [(3.0, 4.0), (10.5, 6.2), (25.0, 15.0)]
    s.begin_stroke(1, pts[0], 1.5)
    for p in pts[1:]:
        s.stroke_to(p, 1.5)
    atom = the_atom(s.end_stroke())
    under = np.zeros_like(base, dtype=bool)
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        under |= brute_capsule(base.shape, a, b, 1.5)
    expected = base.copy()
    expected[under] = 1
    np.testing.assert_array_equal(tex.grid.indices, expected)
    assert atom is not None and atom.count == int(under.sum())


def test_one_stroke_is_one_undo_step_and_undo_redo_are_exact():
    rng = np.random.default_rng(1)
    base = rng.integers(0, 3, (40, 50), dtype=np.uint8)
    tex = make_texture(base.copy())
    s = EditDocument(tex)
    s.fill_rect((0, 0), (5, 5), 3)
    after_rect = tex.grid.indices.copy()
    s.begin_stroke(3, (10, 10), 2)
    for k in range(1, 30):
        s.stroke_to((10 + k, 10 + 0.7 * k), 2)
    s.end_stroke()
    after_stroke = tex.grid.indices.copy()
    assert not np.array_equal(after_rect, after_stroke)
    # One undo removes the whole stroke, the second the rectangle.
    s.undo()
    np.testing.assert_array_equal(tex.grid.indices, after_rect)
    s.undo()
    np.testing.assert_array_equal(tex.grid.indices, base)
    assert not s.history.can_undo and s.undo() is None
    s.redo()
    s.redo()
    np.testing.assert_array_equal(tex.grid.indices, after_stroke)
    assert s.history.redo_label is None


def test_overlapping_dabs_undo_to_original_values():
    base = np.arange(15 * 15, dtype=np.uint8).reshape(15, 15) % 3
    tex = make_texture(base.copy())
    s = EditDocument(tex)
    s.begin_stroke(3, (7, 7), 3)
    s.stroke_to((8, 7), 3)
    s.stroke_to((7, 7), 3)
    atom = the_atom(s.end_stroke())
    assert isinstance(atom, EditAtom)
    assert int((tex.grid.indices != base).sum()) == atom.count
    s.undo()
    np.testing.assert_array_equal(tex.grid.indices, base)


def test_new_edit_clears_redo():
    tex = make_texture(np.zeros((6, 6), dtype=np.uint8))
    s = EditDocument(tex)
    s.fill_rect((0, 0), (1, 1), 1)
    s.undo()
    assert s.history.redo_label is not None
    s.fill_rect((3, 3), (4, 4), 2)
    assert s.history.redo_label is None


def test_flood_fill_stops_at_other_indices():
    g = np.array(
        [
            [0, 0, 1, 0, 0],
            [0, 0, 1, 0, 0],
            [1, 1, 1, 0, 0],
            [0, 0, 0, 2, 2],
            [0, 0, 2, 0, 0],
        ],
        dtype=np.uint8,
    )
    tex = make_texture(g.copy())
    s = EditDocument(tex)
    s.flood_fill((0, 0), 3)
    expected = g.copy()
    expected[:2, :2] = 3  # only the top-left pocket of zeros, walled in by 1s
    np.testing.assert_array_equal(tex.grid.indices, expected)
    # Four-connectivity does not leak through the corner between the 1s and 2s.
    fp4 = full_mask(flood_footprint(g, (3, 0)), g.shape)
    assert fp4[0, 3] and not fp4[3, 0] and not fp4[4, 4]


def test_rect_fill_inclusive_any_order_and_clipped():
    tex = make_texture(np.zeros((6, 8), dtype=np.uint8))
    s = EditDocument(tex)
    s.fill_rect((6.2, 4.4), (2.0, 1.0), 2)  # corners round to (6, 4) and (2, 1)
    expected = np.zeros((6, 8), dtype=np.uint8)
    expected[1:5, 2:7] = 2
    np.testing.assert_array_equal(tex.grid.indices, expected)
    fp = rect_footprint((6, 8), (-5, -5), (100, 1))
    assert (fp.rows, fp.cols) == (slice(0, 2), slice(0, 8))
    assert rect_footprint((6, 8), (20, 20), (30, 30)).empty


def test_eyedropper_picks_nearest_vertex():
    g = np.zeros((4, 4), dtype=np.uint8)
    g[2, 3] = 3
    s = EditDocument(make_texture(g))
    assert s.pick((2.6, 1.7)) == 3
    assert s.pick((2.4, 1.7)) == 0
    assert s.pick((-2, 0)) is None


def test_atom_memory_grows_with_the_edit_not_the_map():
    small = make_texture(np.zeros((101, 101), dtype=np.uint8))
    big = make_texture(np.zeros((2049, 2049), dtype=np.uint8))
    sizes = []
    for tex in (small, big):
        s = EditDocument(tex)
        s.begin_stroke(1, (20, 20), 3)
        s.stroke_to((40, 30), 3)
        sizes.append(s.end_stroke().nbytes)
    assert sizes[0] == sizes[1]
    # A long diagonal stroke stays proportional to the vertices it changed.
    s = EditDocument(big)
    s.begin_stroke(2, (0, 0), 1)
    for k in range(1, 200):
        s.stroke_to((10 * k, 10 * k), 1)
    atom = the_atom(s.end_stroke())
    assert atom.nbytes < 3 * atom.count
    assert atom.nbytes < big.grid.indices.nbytes / 50


def test_events_report_the_changed_box():
    tex = make_texture(np.zeros((10, 10), dtype=np.uint8))
    s = EditDocument(tex)
    seen: list[GridChange] = []
    unsubscribe = s.events.grid.connect(seen.append)
    s.fill_rect((2, 3), (4, 5), 1)
    assert seen == [GridChange(slice(3, 6), slice(2, 5))]
    s.fill_rect((2, 3), (4, 5), 1)  # no change -> no event, no undo step
    assert len(seen) == 1
    s.undo()
    assert seen[-1] == GridChange(slice(3, 6), slice(2, 5))
    unsubscribe()
    s.redo()
    assert len(seen) == 2


def test_dirty_region_covers_touched_cells_plus_one():
    # Vertex rows 3..5, cols 2..4 of a 10x10-cell grid: cells rows 2..5, cols 1..4 touched,
    # plus one cell margin: rows 1..6, cols 0..5.
    rows, cols = dirty_cells(GridChange(slice(3, 6), slice(2, 5)), (10, 10), margin=1)
    assert (rows, cols) == (slice(1, 7), slice(0, 6))
    assert dirty_region(GridChange(slice(3, 6), slice(2, 5)), (10, 10), (4, 2)) == (0, 2, 24, 12)
    # Clipped at the far edge.
    rows, cols = dirty_cells(GridChange(slice(9, 11), slice(10, 11)), (10, 10))
    assert (rows, cols) == (slice(7, 10), slice(8, 10))


def test_replace_grid_is_one_undo_step():
    base = np.zeros((8, 9), dtype=np.uint8)
    tex = make_texture(base.copy())
    s = EditDocument(tex)
    new = np.random.default_rng(3).integers(0, 4, base.shape, dtype=np.uint8)
    atom = the_atom(s.replace_grid(new))
    assert isinstance(atom, MultiAtom)
    np.testing.assert_array_equal(tex.grid.indices, new)
    s.undo()
    np.testing.assert_array_equal(tex.grid.indices, base)
    with pytest.raises(TerrathemeError, match="shape"):
        s.replace_grid(np.zeros((3, 3), dtype=np.uint8))


def test_replace_grid_with_the_same_grid_records_nothing():
    base = np.arange(72, dtype=np.uint8).reshape(8, 9) % 3
    tex = make_texture(base.copy(), k=3)
    s = EditDocument(tex)
    assert s.replace_grid(base.copy()) is None
    assert not s.history.can_undo
    np.testing.assert_array_equal(tex.grid.indices, base)


def test_errors_name_the_problem():
    s = EditDocument(make_texture(np.zeros((5, 5), dtype=np.uint8), k=2))
    with pytest.raises(TerrathemeError, match="theme index 7"):
        s.fill_rect((0, 0), (1, 1), 7)
    with pytest.raises(TerrathemeError, match="radius"):
        s.begin_stroke(1, (0, 0), -1)
    with pytest.raises(TerrathemeError, match="without begin_stroke"):
        s.stroke_to((1, 1), 1)
    with pytest.raises(TerrathemeError, match="not finite"):
        s.fill_rect((float("nan"), 0), (1, 1), 1)
