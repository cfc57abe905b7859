"""A classification of a document's photo, and its result as the changes it makes (no Qt).

:func:`run_classification` runs the editor's Classify request through the one
conversion step (:mod:`core.convert.step`); :func:`classification_changes` checks the
result against the document and lists its undoable changes in the order they apply
(themes, then grid, then the rest), committed as one undo step.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum

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
from terratheme.core.edit.uncertainty import next_kept_prior, scribble_classes
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.themes.library import Theme, ThemeLibrary


@dataclass(frozen=True)
class ClassificationUpdate:
    """A classification result to put in a document.

    ``indices`` (gh+1, gw+1): the new grid, indexing the current themes then
    ``new_themes`` (the themes cut from the photo), or ``new_themes`` alone with
    ``replace_themes``. ``confidence`` (H, W) float in [0, 1] replaces the old map
    (None clears it). ``scribble_classes``, ``class_weights``: scribble runs' classes
    and prior weights (:func:`~core.edit.uncertainty.next_kept_prior`); None: unchanged.
    ``colour_map``: with ``replace_themes``, the map fitted to the new themes (None: none).
    """

    indices: np.ndarray
    new_themes: Sequence[Theme] = ()
    replace_themes: bool = False
    confidence: np.ndarray | None = None
    scribble_classes: frozenset[int] | None = None
    class_weights: Mapping[int, float] | None = None
    colour_map: ColourMap | None = None


def classification_changes(data: DocumentData, update: ClassificationUpdate) -> list[Change]:
    """The changes that put a classification result in place (empty: nothing changes).

    Everything is checked first: TerrathemeError for no themes to replace the library
    with, or a grid or confidence map that does not fit. ``data`` is not changed.
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
    # New themes of their own: the colour map fitted to the old ones goes (or theirs comes).
    grid = grid_replacement(data, u.indices, len(library), repaint_map=not u.replace_themes)
    if u.replace_themes and data.texture.colour_map is not u.colour_map:
        changes.append(SetColourMap(data.texture.colour_map, u.colour_map))
    # Themes first (the new grid refers to them), then the grid, then the rest.
    n_themes = sum(isinstance(c, SetLibrary | AppendTheme) for c in changes)
    changes[n_themes:n_themes] = grid
    return changes


#: display colours of new class themes (matplotlib's tab10, as 8-bit RGB)
_QUALITATIVE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
                (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))


class ClassifyMode(Enum):
    """What the editor's Classify menu runs on a project's photo."""


    UNSUPERVISED_MAP = "Unsupervised, map classes to the current themes"
    UNSUPERVISED_NEW = "Unsupervised, new themes cut from the photo"
    SCRIBBLES = "From scribbles (random forest)"
    AERIAL = "Shipped aerial model (building, land, road, vegetation, water)"


def class_themes(photo: np.ndarray, labels: np.ndarray, classes: tuple[int, ...],
                 taken: list[str], cell: tuple[int, int],
                 names: Mapping[int, str] | None = None) -> tuple[list[Theme], np.ndarray]:
    """Themes cut from the photo for every class, their patches where ``convert`` cuts
    them (``core.convert.step.assign_themes``, or ``sample_themes`` on a photo larger than
    a region's sample, its windows moved onto classes a ``cell`` grid shows and they miss).

    Returns the themes (renamed where a name is taken, and given distinct
    display colours so the index map reads well; the texture keeps the
    photo's look) and the class -> position-in-that-list table.
    """
    from terratheme.core.convert.labels_to_grid import apply_lut, labels_to_grid
    from terratheme.core.convert.region_sample import photo_sample
    from terratheme.core.convert.step import assign_themes, cover_classes, sample_themes

    rgb = photo[..., :3]
    sample = photo_sample(rgb, labels)
    if sample is None:
        mapping = assign_themes(rgb, labels, classes, names=names)
    else:
        mapping = sample_themes(sample, classes, names=names, detail=None)
        grid = labels_to_grid(apply_lut(labels, mapping.lut), cell, keep_specks=False)
        _, mapping = cover_classes(
            sample, classes, mapping, grid, labels.shape[::-1],
            lambda covering: photo_sample(rgb, labels, covering=covering),
            names=names, detail=None)
    out = []
    for i, theme in enumerate(mapping.library):
        name = theme.name
        while name.lower() in (t.lower() for t in taken):
            name += "'"
        taken.append(name)
        colour = _QUALITATIVE[i % len(_QUALITATIVE)]
        out.append(theme.with_(name=name, colour=colour))
    return out, mapping.lut.astype(np.int64)


def run_classification(mode: ClassifyMode, photo: np.ndarray, scribbles: np.ndarray | None,
                       library: ThemeLibrary, cell: tuple[int, int], grid_shape: tuple[int, int],
                       progress, class_weights: Mapping[int, float] | None = None,
                       position: bool = False, replace_themes: bool = False
                       ) -> tuple[ClassificationUpdate, int]:
    """Classify ``photo``, convert the labels to a ``grid_shape`` vertex grid.

    Returns the update to apply (:meth:`EditDocument.apply_classification`) and the
    number of classes. ``class_weights``, ``position``: scribbles only (kept prior
    weights; strokes' position as a feature). ``replace_themes``: the new themes
    replace ``library`` (a new project), so their names need not differ from it.
    """
    from terratheme.core.classify import SupervisedOptions, load_model
    from terratheme.core.convert.colour_fit import ColourMapOptions
    from terratheme.core.convert.labels_to_grid import apply_lut, labels_to_grid
    from terratheme.core.convert.step import (
        assign_themes,
        calm_vertices,
        classify_photo,
        detail_mapping,
        fit_colour_map,
        grid_budget,
    )
    from terratheme.core.themes.from_photo import ThemeMapping

    # New themes follow the library, or replace it (their names then need not differ).
    taken, offset = ([], 0) if replace_themes else (list(library.names), len(library))
    # The one conversion step of core (core.convert.step), as terratheme convert runs it.
    if mode is ClassifyMode.SCRIBBLES:
        if scribbles is None or not scribbles.any():
            raise TerrathemeError("no scribbles: paint some with the Scribble tool (S) first")
        result, model = classify_photo(photo, scribbles=scribbles,
                                       supervised=SupervisedOptions().with_positions(position),
                                       class_weights=class_weights, progress=progress)
        weights = (None if model.class_weights is None else
                   dict(zip(model.classes, model.class_weights, strict=True)))
        painted = scribble_classes(scribbles)
        # Scribble value v marks theme v - 1.
        lut = np.clip(np.arange(256) - 1, 0, len(library) - 1)
        new_themes: list[Theme] = []
    elif mode is ClassifyMode.AERIAL:
        # The shipped classifier: new themes cut from the photo, named by its classes.
        weights, painted = None, None
        model = load_model("aerial")
        result, _ = classify_photo(photo, model=model, progress=progress)
        new_themes, lut = class_themes(photo, result.labels, result.classes, taken, cell,
                                       names=model.class_names)
        lut = lut + offset
    else:
        weights, painted = None, None
        result, _ = classify_photo(photo, progress=progress)
        labels, classes = result.labels, result.classes
        if mode is ClassifyMode.UNSUPERVISED_MAP:
            # Each class to its nearest current theme, by the rule convert --themes uses.
            lut = assign_themes(photo[..., :3], labels, classes, library).lut.astype(np.int64)
            new_themes = []
        else:
            new_themes, lut = class_themes(photo, labels, classes, taken, cell)
            lut = lut + offset
    # Lone specks removed, as convert does (core.convert.specks).
    theme_labels = apply_lut(result.labels, lut)
    grid = labels_to_grid(theme_labels, cell, keep_specks=False)
    if grid.indices.shape != grid_shape:
        raise TerrathemeError(
            f"the photo ({photo.shape[1]} x {photo.shape[0]}) gives a {grid.indices.shape} grid "
            f"with cell {cell}; the project grid is {grid_shape}")
    colour_map = None
    if replace_themes and new_themes:
        # A new project gets what convert makes: detail themes with their calm twins under
        # a fitted colour map.
        rgb = photo[..., :3]
        detail, twin_labels = detail_mapping(rgb, theme_labels, ThemeMapping(
            ThemeLibrary(new_themes), lut.astype(np.uint8), tuple(result.classes)))
        options = ColourMapOptions()
        grid, detail = calm_vertices(rgb, theme_labels, grid, detail,
                                     grid_budget(options, theme_labels.size),
                                     twin_labels=twin_labels)
        new_themes = list(detail.library)
        colour_map = fit_colour_map(rgb, grid, detail.library, options).colour_map
    update = ClassificationUpdate(grid.indices, new_themes, replace_themes,
                                  np.asarray(result.confidence, np.float32), painted, weights,
                                  colour_map)
    return update, len(result.classes)
