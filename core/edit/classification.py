"""A classification result as the changes it makes to a document (no Qt).

A classifier's run gives a new grid, themes cut from the photo, a confidence
map and, for scribble runs, the class prior to keep
(:mod:`core.edit.uncertainty`). :class:`ClassificationUpdate` holds it;
:func:`classification_changes` checks all of it against the document and
lists the undoable changes (:mod:`core.edit.changes`) that put it in place,
in the order they apply:
the themes first (the new grid refers to them), then the grid, then the
rest. :meth:`core.edit.document.EditDocument.apply_classification` commits
them as one undo step.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from terratheme.core.edit.changes import (
    AppendTheme,
    Change,
    SetColourMap,
    SetLibrary,
    SetPrior,
    SwapLayer,
    grid_replacement,
)
from terratheme.core.edit.layers import DocumentData, Layer, validate_confidence
from terratheme.core.edit.uncertainty import next_kept_prior
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.library import Theme, ThemeLibrary


@dataclass(frozen=True)
class ClassificationUpdate:
    """A classification result to put in a document.

    Attributes
    ----------
    indices : (gh+1, gw+1) integer ndarray
        The new grid, indexing the library after the change: the current
        themes then ``new_themes``, or (``replace_themes``) ``new_themes`` alone.
    new_themes : sequence of Theme
        Themes cut from the photo for the classes.
    replace_themes : bool
        The library becomes ``new_themes`` (a project just started over a photo).
    confidence : (H, W) float ndarray in [0, 1] or None
        Replaces the old map (None clears it: it was another result's).
    scribble_classes, class_weights :
        Scribble runs: the classes trained on and the model's class-prior
        weights (:func:`~core.edit.uncertainty.next_kept_prior`); None: unchanged.
    """

    indices: np.ndarray
    new_themes: Sequence[Theme] = ()
    replace_themes: bool = False
    confidence: np.ndarray | None = None
    scribble_classes: frozenset[int] | None = None
    class_weights: Mapping[int, float] | None = None


def classification_changes(data: DocumentData, update: ClassificationUpdate) -> list[Change]:
    """The changes that put a classification result in place (empty: nothing changes).

    ``data`` is the document's, unchanged here. Everything is checked before
    the list is made.

    Raises
    ------
    TerrathemeError
        No themes to replace the library with; a grid or confidence map that
        does not fit.
    """
    u = update
    old_library = data.texture.library
    if u.replace_themes:
        library = ThemeLibrary(u.new_themes)
        if not len(library):
            raise TerrathemeError("a classification that replaces the themes needs themes")
    else:
        library = ThemeLibrary([*old_library, *u.new_themes])
    changes: list[Change] = []
    if u.replace_themes and library != old_library:
        changes.append(SetLibrary(old_library, library))
    elif not u.replace_themes:
        changes += [AppendTheme(t) for t in u.new_themes]
    new_conf = None if u.confidence is None else validate_confidence(u.confidence,
                                                                      data.texture.photo)
    if new_conf is not None or data.confidence is not None:
        changes.append(SwapLayer(Layer.CONFIDENCE, data.confidence, new_conf))
    if u.scribble_classes is not None:
        prior = next_kept_prior(data.kept_prior, frozenset(u.scribble_classes), u.class_weights)
        if prior != data.kept_prior:
            changes.append(SetPrior(data.kept_prior, prior))
    # New themes of their own: the colour map fitted to the old ones goes.
    grid = grid_replacement(data, u.indices, len(library), neutral=not u.replace_themes)
    if u.replace_themes and data.texture.colour_map is not None:
        changes.append(SetColourMap(data.texture.colour_map, None))
    # Themes first (the new grid refers to them), then the grid, then the rest.
    n_themes = sum(isinstance(c, SetLibrary | AppendTheme) for c in changes)
    changes[n_themes:n_themes] = grid
    return changes
