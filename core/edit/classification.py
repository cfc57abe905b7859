"""A classification result as the changes it makes to a document (no Qt).

A classifier's run gives a new grid, themes cut from the photo, a confidence
map and, for scribble runs, the class prior to keep
(:mod:`core.edit.uncertainty`). :func:`classification_changes` checks all of
it against the document and lists the undoable changes
(:mod:`core.edit.changes`) that put it in place, in the order they apply:
the themes first (the new grid refers to them), then the grid, then the
rest. :meth:`core.edit.document.EditDocument.apply_classification` commits
them as one undo step.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from core.edit.changes import (
    AppendTheme,
    Change,
    SetColourMap,
    SetLibrary,
    SetPrior,
    SwapLayer,
    grid_replacement,
)
from core.edit.layers import DocumentData, Layer, validate_confidence
from core.edit.uncertainty import next_kept_prior
from core.errors import TerrathemeError
from core.themes.library import Theme, ThemeLibrary


def classification_changes(
    data: DocumentData,
    indices: np.ndarray,
    *,
    new_themes: Sequence[Theme] = (),
    replace_themes: bool = False,
    confidence: np.ndarray | None = None,
    scribble_classes: frozenset[int] | None = None,
    class_weights: Mapping[int, float] | None = None,
) -> list[Change]:
    """The changes that put a classification result in place (empty: nothing changes).

    Parameters as :meth:`core.edit.document.EditDocument.apply_classification`;
    ``data`` is the document's, unchanged here. Everything is checked before
    the list is made.

    Raises
    ------
    TerrathemeError
        No themes to replace the library with; a grid or confidence map that
        does not fit.
    """
    old_library = data.texture.library
    if replace_themes:
        library = ThemeLibrary(new_themes)
        if not len(library):
            raise TerrathemeError("a classification that replaces the themes needs themes")
    else:
        library = ThemeLibrary([*old_library, *new_themes])
    changes: list[Change] = []
    if replace_themes and library != old_library:
        changes.append(SetLibrary(old_library, library))
    elif not replace_themes:
        changes += [AppendTheme(t) for t in new_themes]
    new_conf = None if confidence is None else validate_confidence(confidence, data.texture.photo)
    if new_conf is not None or data.confidence is not None:
        changes.append(SwapLayer(Layer.CONFIDENCE, data.confidence, new_conf))
    if scribble_classes is not None:
        prior = next_kept_prior(data.kept_prior, frozenset(scribble_classes), class_weights)
        if prior != data.kept_prior:
            changes.append(SetPrior(data.kept_prior, prior))
    # New themes of their own: the colour map fitted to the old ones goes.
    grid = grid_replacement(data, indices, len(library), neutral=not replace_themes)
    if replace_themes and data.texture.colour_map is not None:
        changes.append(SetColourMap(data.texture.colour_map, None))
    # Themes first (the new grid refers to them), then the grid, then the rest.
    n_themes = sum(isinstance(c, SetLibrary | AppendTheme) for c in changes)
    changes[n_themes:n_themes] = grid
    return changes
