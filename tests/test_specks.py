"""Lone single-vertex specks: removed by their neighbours' theme, on every conversion path."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from terratheme.core.convert.cell_choice import agreement, choose_cell_size
from terratheme.core.convert.labels_to_grid import apply_lut, labels_to_grid, vote_grid
from terratheme.core.convert.photo import ConvertOptions, convert_photo
from terratheme.core.convert.specks import SpeckStream, clean_rows, remove_specks
from terratheme.core.convert.tiled import grid_from_file
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import write_image


def _grid(text: str) -> np.ndarray:
    return np.array([[int(c) for c in line.split()] for line in text.strip().splitlines()],
                    np.uint8)


def test_a_lone_vertex_in_a_field_takes_the_field():
    g = np.zeros((5, 5), np.uint8)
    g[2, 2] = 3
    assert (remove_specks(g) == 0).all()
    assert g[2, 2] == 3  # the input is not changed


def test_lone_vertices_at_a_corner_and_an_edge():
    g = _grid("""
        4 1 1 1
        1 1 1 2
        1 1 1 1
        """)
    assert (remove_specks(g) == 1).all()


def test_two_adjacent_lone_vertices_of_different_themes_both_take_the_field():
    g = np.full((4, 6), 2, np.uint8)
    g[1, 2], g[1, 3] = 5, 7
    assert (remove_specks(g) == 2).all()


def test_a_diagonal_line_and_a_pair_are_kept():
    g = _grid("""
        3 0 0 0 0 0
        0 3 0 0 0 0
        0 0 3 0 5 5
        0 0 0 3 0 0
        """)
    np.testing.assert_array_equal(remove_specks(g), g)


def test_ties_go_to_the_lowest_index_and_the_decision_uses_the_original_grid():
    # The 9 has 4 neighbours of 2 and 4 of 6: the lowest, 2; with 2 -> 7 and 6 -> 3, 3.
    g = _grid("""
        2 2 6 6 6
        2 2 6 6 6
        2 2 9 6 6
        2 2 2 6 2
        2 2 2 2 2
        """)
    want = g.copy()
    want[2, 2] = 2
    np.testing.assert_array_equal(remove_specks(g), want)
    swapped = np.arange(256, dtype=np.uint8)
    swapped[[2, 6]] = 7, 3
    want = swapped[g]
    want[2, 2] = 3
    np.testing.assert_array_equal(remove_specks(swapped[g]), want)
    # A checkerboard: every vertex shares its theme with its diagonal neighbours: kept.
    board = (np.indices((4, 4)).sum(axis=0) % 2).astype(np.uint8)
    np.testing.assert_array_equal(remove_specks(board), board)
    # Two lone vertices of a column, a field row between them: both take the field.
    lone_col = _grid("""
        1 1 1
        1 4 1
        1 1 1
        1 7 1
        1 1 1
        """)
    np.testing.assert_array_equal(remove_specks(lone_col), np.ones((5, 3), np.uint8))


def test_lone_next_to_lone_uses_the_original_values_in_any_order():
    # 8 and 9 are lone neighbours: each sees the other's original theme, not the cleaned one.
    g = _grid("""
        1 1 2 2
        1 8 9 2
        1 1 2 2
        """)
    want = _grid("""
        1 1 2 2
        1 1 2 2
        1 1 2 2
        """)
    np.testing.assert_array_equal(remove_specks(g), want)
    np.testing.assert_array_equal(remove_specks(g[::-1, ::-1]), want[::-1, ::-1])


def test_tiny_grids():
    np.testing.assert_array_equal(remove_specks(np.array([[5]], np.uint8)), [[5]])
    # Each vertex judged on the original grid: two lone vertices swap, the ends of 5 6 5 too.
    np.testing.assert_array_equal(remove_specks(np.array([[5, 6]], np.uint8)), [[6, 5]])
    np.testing.assert_array_equal(remove_specks(np.array([[5, 6, 5]], np.uint8)), [[6, 5, 6]])
    np.testing.assert_array_equal(remove_specks(np.array([[5, 6], [6, 6]], np.uint8)),
                                  [[6, 6], [6, 6]])
    assert remove_specks(np.zeros((0, 3), np.uint8)).shape == (0, 3)


def test_bands_equal_one_pass(monkeypatch):
    import terratheme.core.convert.specks as cs

    rng = np.random.default_rng(3)
    g = rng.integers(0, 3, (37, 23)).astype(np.uint8)
    whole = remove_specks(g)
    monkeypatch.setattr(cs, "_BAND_VERTICES", 23 * 4)
    np.testing.assert_array_equal(remove_specks(g), whole)
    # The naive rule, vertex by vertex on the original grid.
    want = g.copy()
    for r in range(37):
        for c in range(23):
            nbs = [int(g[y, x]) for y in range(max(r - 1, 0), min(r + 2, 37))
                   for x in range(max(c - 1, 0), min(c + 2, 23)) if (y, x) != (r, c)]
            if g[r, c] not in nbs:
                counts = np.bincount(nbs, minlength=256)
                want[r, c] = int(np.argmax(counts))
    np.testing.assert_array_equal(whole, want)
    assert (whole != g).any()


def test_stream_equals_the_whole_grid_for_any_order_of_reports():
    rng = np.random.default_rng(5)
    g = rng.integers(0, 4, (20, 9)).astype(np.uint8)
    want = remove_specks(g)
    for reports in ([20], [1, 2, 3, 20], [5, 5, 3, 12, 19, 20], list(range(21))):
        filling = np.zeros_like(g)
        stream = SpeckStream(filling)
        done = cleaned = 0
        for final in reports:
            filling[done:final] = g[done:final]
            done = max(done, final)
            # A row is cleaned once the row below is final; the last row with it.
            cleaned = max(cleaned, 20 if final == 20 else final - 1)
            assert stream.advance(final) == cleaned
            np.testing.assert_array_equal(filling[:cleaned], want[:cleaned])
        np.testing.assert_array_equal(stream.finish(), want)


def test_clean_rows_treats_the_window_edge_as_the_grid_edge():
    w = _grid("""
        1 1 1
        1 3 1
        """)
    np.testing.assert_array_equal(clean_rows(w, 1, 2), [[1, 1, 1]])
    np.testing.assert_array_equal(clean_rows(w, 0, 1), [[1, 1, 1]])


def test_errors():
    with pytest.raises(TerrathemeError, match="2-D uint8"):
        remove_specks(np.zeros((3, 3), np.int32))
    with pytest.raises(TerrathemeError, match="2-D uint8"):
        SpeckStream(np.zeros(4, np.uint8))


def test_vote_grid_keeps_specks_unless_asked():
    labels = np.zeros((32, 32), np.uint8)
    labels[14:18, 14:18] = 2  # one vertex's window at cell 4
    kept = vote_grid(labels, (4, 4))
    assert kept[4, 4] == 2 and (np.delete(kept.ravel(), 4 * 9 + 4) == 0).all()
    assert (vote_grid(labels, (4, 4), keep_specks=False) == 0).all()
    assert (labels_to_grid(labels, 4, keep_specks=False).indices == 0).all()
    assert labels_to_grid(labels, 4).indices[4, 4] == 2


def test_cell_choice_is_measured_on_the_cleaned_grid():
    # A field with islands of one vertex at cell 8: kept, the label view holds them.
    labels = np.zeros((96, 96), np.uint8)
    for y, x in ((16, 16), (48, 64), (80, 32)):
        labels[y - 4:y + 4, x - 4:x + 4] = 1
    kept = choose_cell_size(labels, 0.5, candidates=[8])
    removed = choose_cell_size(labels, 0.5, candidates=[8], keep_specks=False)
    # Cleaned, the grid is all field: the islands' 3 * 64 pixels are lost.
    assert removed.curve[0].agreement == pytest.approx(1 - 3 * 64 / 96**2)
    assert kept.curve[0].agreement > removed.curve[0].agreement


def _classes(pixels: np.ndarray) -> np.ndarray:
    return np.argmax(pixels[..., :3], axis=2).astype(np.uint8) + 1


@pytest.mark.parametrize(("cell", "tile"), [((8, 8), 64), ((5, 7), 40), (3, 17)])
def test_tiled_grid_without_specks_equals_the_whole_vote(tmp_path, cell, tile):
    rng = np.random.default_rng(11)
    img = rng.integers(0, 256, (101, 131, 3), dtype=np.uint8)
    path = tmp_path / "photo.tif"
    write_image(path, img, tile=32)
    size = cell if isinstance(cell, tuple) else (cell, cell)
    want = vote_grid(_classes(img), size, keep_specks=False)
    assert (want != vote_grid(_classes(img), size)).any()
    seen = []

    def rows_final(grid, rows):
        # Reported rows are final: they already hold the cleaned values.
        np.testing.assert_array_equal(grid.indices[:rows], want[:rows])
        seen.append(rows)

    got = grid_from_file(path, cell, _classes, tile=tile, overlap=0, keep_specks=False,
                         rows_final=rows_final)
    np.testing.assert_array_equal(got.indices, want)
    assert seen[-1] == want.shape[0] and seen == sorted(seen)


def test_convert_chooses_the_cell_on_the_grid_it_keeps():
    # Sand with 12 dark 8 x 8 islands: one vertex each at cell 8, fewer at larger cells.
    rng = np.random.default_rng(2)
    img = np.empty((128, 128, 3), np.float64)
    img[:] = (225, 200, 140)
    for i in range(12):
        y, x = 16 + 32 * (i // 4), 16 + 32 * (i % 4)
        img[y - 4:y + 4, x - 4:x + 4] = (40, 40, 60)
    img = np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)
    opts = ConvertOptions(themes=2, colour_map=None, full_curve=True)
    kept = convert_photo(img, replace(opts, keep_specks=True))
    removed = convert_photo(img, opts)
    assert not ConvertOptions().keep_specks
    theme_labels = apply_lut(removed.labels, removed.mapping.lut)
    # Without its specks the islands' class loses IoU at cell 8: the choice sees it.
    at8 = {p.cell: p for p in removed.choice.curve}[8]
    assert at8.worst_class_iou < {p.cell: p for p in kept.choice.curve}[8].worst_class_iou
    assert removed.choice.cell[0] < kept.choice.cell[0]
    # The curve was measured on the grid the project holds.
    assert removed.agreement == pytest.approx(agreement(theme_labels, removed.project.grid))
    np.testing.assert_array_equal(removed.project.grid.indices,
                                  remove_specks(vote_grid(theme_labels, removed.choice.cell)))


def test_cli_removes_specks_unless_kept(tmp_path, capsys):
    from terratheme.app.cli import main
    from terratheme.core.model.project import load_project

    # A sand field with one dark vertex window at cell 8 (the vertex at (3, 4)).
    rng = np.random.default_rng(4)
    img = np.empty((64, 96, 3), np.float64)
    img[:] = (225, 200, 140)
    img[:, 72:] = (40, 90, 200)
    img[20:28, 28:36] = (30, 30, 40)
    img = np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)
    photo = tmp_path / "photo.png"
    write_image(photo, img)
    for flag in ([], ["--specks", "keep"]):
        out = tmp_path / f"p{len(flag)}.ttproj"
        assert main(["convert", str(photo), str(out), "--cell", "8", "--themes", "3",
                     "--colour-map", "off", *flag]) == 0
    removed, kept = (load_project(tmp_path / f"p{k}.ttproj").grid.indices for k in (0, 2))
    assert kept[3, 4] != kept[3, 3] and removed[3, 4] == removed[3, 3] == kept[3, 3]
    np.testing.assert_array_equal(np.delete(removed.ravel(), 3 * 13 + 4),
                                  np.delete(kept.ravel(), 3 * 13 + 4))
    with pytest.raises(SystemExit) as exc:
        main(["convert", str(photo), str(tmp_path / "x.ttproj"), "--specks", "drop"])
    assert exc.value.code == 2
    assert "invalid choice: 'drop'" in capsys.readouterr().err
