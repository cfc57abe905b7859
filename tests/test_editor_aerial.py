"""The editor's Classify > Shipped aerial model: new themes cut from the photo, named by class."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from terratheme.core.classify import shipped_models
from terratheme.core.convert.labels_to_grid import labels_to_grid
from terratheme.core.edit.classification import ClassifyMode as Mode
from terratheme.core.edit.classification import run_classification
from terratheme.core.io.images import read_image
from terratheme.core.themes.library import ThemeLibrary, flat_theme

SAMPLE = Path(__file__).resolve().parents[1] / "sample_maps" / "dubai_marina.jpg"

pytestmark = pytest.mark.skipif("aerial" not in shipped_models(),
                                reason="the shipped aerial model is not in models/")


def test_aerial_mode_appends_themes_named_after_the_models_classes():
    photo = np.ascontiguousarray(read_image(SAMPLE)[60:252, 600:856, :3])
    library = ThemeLibrary([flat_theme("land", (200, 190, 170))])  # a name already taken
    cell = (16, 16)
    shape = labels_to_grid(np.zeros(photo.shape[:2], np.uint8), cell).indices.shape
    result, _ = run_classification(Mode.AERIAL, photo, None, library, cell, shape, None)
    legend = set(shipped_models()["aerial"].class_names.values())
    names = [t.name for t in result.new_themes]
    assert names and all(n.rstrip("'") in legend for n in names)
    assert "land" not in names  # the taken name is made distinct
    # Indices point past the existing themes, at the appended ones.
    assert result.indices.min() >= len(library)
    assert result.indices.max() < len(library) + len(result.new_themes)
    assert result.confidence.shape == photo.shape[:2]


def _lone_vertices(indices: np.ndarray) -> int:
    """Vertices none of whose 8 neighbours inside the grid shares their index (a plain loop)."""
    rows, cols = indices.shape
    count = 0
    for r in range(rows):
        for c in range(cols):
            around = [indices[rr, cc] for rr in range(max(r - 1, 0), min(r + 2, rows))
                      for cc in range(max(c - 1, 0), min(c + 2, cols)) if (rr, cc) != (r, c)]
            count += bool(around) and indices[r, c] not in around
    return count


def test_the_editors_grid_has_no_lone_specks_as_convert_does():
    photo = np.ascontiguousarray(read_image(SAMPLE)[:, :, :3])
    library = ThemeLibrary([flat_theme("land", (200, 190, 170))])
    cell = (16, 16)
    shape = labels_to_grid(np.zeros(photo.shape[:2], np.uint8), cell).indices.shape
    result, _ = run_classification(Mode.AERIAL, photo, None, library, cell, shape, None)
    assert _lone_vertices(result.indices) == 0
