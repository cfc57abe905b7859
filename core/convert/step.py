"""The one conversion step every face of terratheme uses: classes -> themes -> grid -> colour map.

``convert`` (:mod:`.photo`), the tiled conversion (:mod:`.tiled`) and the editor all go
through these functions, so a photo gives the same themes everywhere.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
from terratheme.core.classify import (
    Classification,
    SupervisedOptions,
    classify_unsupervised,
    train_classifier,
)
from terratheme.core.convert.cell_choice import (
    DEFAULT_CELL_CANDIDATES,
    CellChoice,
    agreement,
    cell_within_budget,
    choose_cell_size,
    packed_bytes,
)
from terratheme.core.convert.colour_fit import (
    ColourMapOptions,
    FittedColourMap,
    Prediction,
    choose_colour_map,
    grid_prediction,
)
from terratheme.core.convert.labels_to_grid import apply_lut, vote_grid
from terratheme.core.convert.region_sample import RegionSample, covering_sample
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.render.renderer import RenderOptions, render_cells
from terratheme.core.themes.calm import (
    TWIN_MIN_PIXELS,
    CalmTwin,
    class_log_energy,
    fit_calm_twins,
    renumbered,
    split_calm,
    twin_parents,
    twin_vertices,
    with_twins,
)
from terratheme.core.themes.detail import (
    DETAIL_SIGMA,
    detail_themes,
    photo_contrast,
    theme_detail,
)
from terratheme.core.themes.from_photo import (
    ThemeMapping,
    photo_theme_lut,
    themes_by_name,
    themes_from_photo,
)
from terratheme.core.themes.library import ThemeLibrary
from terratheme.core.themes.matching import class_appearances, match_classes, theme_appearances
from terratheme.core.themes.patch_search import PatchOptions, texture_stats

ProgressFn = Callable[[int, int], None]
#: what the themes of a conversion are: "auto"/K (cut from the photo), names, {class: name},
#: or an existing library to map the classes to
ThemesSpec = str | int | Sequence[str] | Mapping[int, str] | ThemeLibrary


def classify_photo(
    rgb: np.ndarray,
    *,
    themes: ThemesSpec = "auto",
    scribbles: np.ndarray | None = None,
    model=None,
    supervised: SupervisedOptions | None = None,
    class_weights: Mapping[int, float] | None = None,
    progress: ProgressFn | None = None,
) -> tuple[Classification, object | None]:
    """``(classification, trained)``: classify a photo the way every conversion does.

    ``model`` first, else an Extra-Trees classifier on ``scribbles`` ((H, W) uint8,
    0 unlabelled; returned as ``trained`` for its prior weights), else unsupervised:
    ``themes`` "auto", K, or names (K from the data, never more than the names).
    """
    if model is not None:
        return model.predict(rgb, progress=progress), None
    if scribbles is not None:
        trained = train_classifier([(rgb, scribbles)], supervised, class_weights=class_weights)
        return trained.predict(rgb, progress=progress), trained
    if isinstance(themes, int | str):
        return classify_unsupervised(rgb, themes=themes, progress=progress), None
    # Names (or a library): K from the data, but never more classes than themes to give.
    n_names = len(themes)
    result = classify_unsupervised(rgb, themes="auto", progress=progress)
    if len(np.unique(result.labels[result.labels > 0])) > n_names:
        result = classify_unsupervised(rgb, themes=n_names, progress=progress)
    return result, None


def assign_themes(rgb: np.ndarray, labels: np.ndarray, classes: Sequence[int],
                  themes: ThemesSpec = "auto", *,
                  patch: PatchOptions = PatchOptions(),
                  names: Mapping[int, str] | None = None) -> ThemeMapping:
    """One theme per class: cut from the photo, shipped by name, or an existing library's.

    ``classes``: those the classifier can give (absent ones get themes too). A
    ``ThemeLibrary`` ``themes``: each class takes its nearest theme (themes may be shared).
    ``names``: with "auto"/K, names of the cut themes (a shipped model's class names).
    """
    if isinstance(themes, ThemeLibrary):
        present = [int(c) for c in classes]
        looks = class_appearances(texture_stats(rgb), labels, present)
        nearest = match_classes(looks, theme_appearances(themes), distinct=False)
        lut = np.zeros(256, np.uint8)
        for c, k in zip(present, nearest, strict=True):
            lut[c] = k
        return ThemeMapping(themes, lut, tuple(present))
    if not cuts_themes(themes):
        return themes_by_name(rgb, labels, themes)
    return themes_from_photo(rgb, labels, classes=classes, options=patch, names=names)


def cuts_themes(themes: ThemesSpec) -> bool:
    """True when :func:`assign_themes` cuts the themes from the photo ("auto" or K)."""
    return isinstance(themes, str | int) and not isinstance(themes, ThemeLibrary)


#: share of a byte budget the packed grid may take (:func:`grid_budget`)
GRID_SHARE = 0.125
#: calm twins may add this share of the class grid's own bytes to a grid over its share
#: (:func:`keep_calm`)
TWIN_GRID_EXTRA = 0.25


def grid_budget(colour_map: ColourMapOptions | None, pixels: int) -> float | None:
    """The ``grid_bpp`` of :func:`themes_and_cell`: ``GRID_SHARE`` of the byte budget
    (:meth:`ColourMapOptions.area_bytes`) of ``pixels``; None without a budget."""
    if colour_map is None or colour_map.target is not None:
        return None
    return GRID_SHARE * colour_map.area_bytes(pixels) * 8 / max(int(pixels), 1)


def budget_entry(colour_map: ColourMapOptions | None) -> dict[str, float]:
    """``{"budget_bpp": bits per photo pixel}`` for a project's colour-map metadata under
    a byte budget; ``{}`` for a dE8 target or no map."""
    if colour_map is None or colour_map.target is not None:
        return {}
    return {"budget_bpp": colour_map.budget}


def detail_sigma(colour_map: ColourMapOptions | None) -> float | None:
    """The ``detail`` of :func:`themes_and_cell`: detail themes need a budget map."""
    return DETAIL_SIGMA if colour_map is not None and colour_map.target is None else None


@dataclass(frozen=True)
class Themed:
    """The themes of a classified photo and, with cell "auto", the cell chosen on them.

    ``theme_labels``: (H, W) uint8 theme index per pixel; ``choice`` (None unless the cell
    was chosen) carries the grid voted at its cell; ``twin_labels``: ``theme_labels`` split
    by ``mapping``'s calm twins when they were fitted on this photo (not a sample), else None.
    """

    mapping: ThemeMapping
    theme_labels: np.ndarray
    choice: CellChoice | None
    twin_labels: np.ndarray | None = None


def themes_and_cell(rgb: np.ndarray, labels: np.ndarray, classes: Sequence[int],
                    themes: ThemesSpec = "auto", *, cell: str | int = "auto",
                    target_agreement: float = 0.9, class_target: float = 0.0,
                    candidates: Sequence[int] = DEFAULT_CELL_CANDIDATES,
                    patch: PatchOptions = PatchOptions(),
                    names: Mapping[int, str] | None = None,
                    full_curve: bool = True,
                    keep_specks: bool = True,
                    detail: float | None = DETAIL_SIGMA,
                    grid_bpp: float | None = None,
                    sample: RegionSample | None = None,
                    calm: Sequence[CalmTwin] | None = None,
                    ) -> Themed:
    """:func:`assign_themes`, and with ``cell`` "auto" the cell choice on its theme labels.

    Themes cut from the photo have their class -> theme table before any is cut, so the
    cell is chosen on a second thread meanwhile (same result). ``detail``: cut themes keep
    only detail finer than this sigma (:func:`detail_themes`); None keeps them whole.
    ``grid_bpp``: the packed grid's bits per photo pixel (:func:`cell_within_budget`).
    ``sample``: the photo's region sample (:func:`.region_sample.photo_sample`): the themes
    are those of :func:`sample_themes`, as a tiled conversion's; the cell still the photo's.
    Detail themes cut from the photo get calm twins (:mod:`core.themes.calm`): ``calm``
    None fits them on this photo, else these are taken.
    """
    def choose(theme_labels: np.ndarray) -> CellChoice:
        choice = choose_cell_size(theme_labels, target_agreement,
                                  candidates=candidates, class_target=class_target,
                                  full_curve=full_curve, keep_specks=keep_specks)
        if grid_bpp is None:
            return choice
        return cell_within_budget(theme_labels, choice, candidates, grid_bpp,
                                  keep_specks=keep_specks)

    if sample is not None:
        mapping = sample_themes(sample, classes, themes, patch=patch, names=names, detail=detail)
        theme_labels = apply_lut(labels, mapping.lut)
        return Themed(mapping, theme_labels, choose(theme_labels) if cell == "auto" else None)
    cut = cuts_themes(themes)
    # Cut themes: the table is known before any theme is cut.
    theme_labels = apply_lut(labels, photo_theme_lut(labels, classes)) if cut else None
    twin_labels = None
    with ThreadPoolExecutor(max_workers=1) as pool:
        job = pool.submit(choose, theme_labels) if cut and cell == "auto" else None
        mapping = assign_themes(rgb, labels, classes, themes, patch=patch, names=names)
        if not cut:
            theme_labels = apply_lut(labels, mapping.lut)
        elif detail is not None:
            mapping, twin_labels = detail_mapping(rgb, theme_labels, mapping, detail, calm=calm)
        choice = job.result() if job is not None else (
            choose(theme_labels) if cell == "auto" else None)
    return Themed(mapping, theme_labels, choice, twin_labels)


def detail_mapping(rgb: np.ndarray, theme_labels: np.ndarray, mapping: ThemeMapping,
                   detail: float = DETAIL_SIGMA, *,
                   calm: Sequence[CalmTwin] | None = None) -> tuple[ThemeMapping, np.ndarray]:
    """``mapping``'s themes as detail themes (:func:`detail_themes`) with their calm twins
    (:mod:`core.themes.calm`; ``calm`` None fits them on this photo, else these are taken,
    renumbered after the themes), each at the photo's contrast on its own pixels; and the
    (H, W) uint8 theme labels split by the twins kept (:func:`split_calm`), for
    :func:`calm_vertices`.

    A twin whose detail texture comes out identical to its theme's (the fragment cap or
    the gain range holding both parts) is dropped: it would cost grid bytes for nothing.
    With twins, the themes made without them are kept too (``plain``: :func:`keep_calm`
    ships them when the grid cannot afford the twins).
    ``rgb``: (H, W, 3) uint8; ``theme_labels``: (H, W) uint8 through ``mapping.lut``.
    """
    n_themes = len(mapping.library)
    if calm is None:
        class_themes = sorted({int(mapping.lut[c]) for c in mapping.classes if c})
        energy = class_log_energy(rgb, theme_labels, class_themes, min_pixels=2 * TWIN_MIN_PIXELS)
        twins = fit_calm_twins(energy, theme_labels, class_themes, n_themes)
    else:
        twins = renumbered(calm, n_themes)
        energy = class_log_energy(rgb, theme_labels, [t.theme for t in twins])
    # Each theme's detail and the photo's contrast once; a twin's detail is its theme's.
    details = [theme_detail(t.texture, detail) for t in mapping.library]
    contrast = photo_contrast(rgb, detail)

    def made(labels: np.ndarray, twins: Sequence[CalmTwin]) -> ThemeLibrary:
        return detail_themes(rgb, labels, with_twins(mapping.library, twins), detail,
                             details=[*details, *(details[t.theme] for t in twins)],
                             contrast=contrast)[0]

    # Each theme's gain on its own pixels: a class's busy part and its calm twin apart.
    split = split_calm(theme_labels, twins, energy)
    themes = made(split, twins)
    # A twin whose detail came out as its theme's (both parts at a cap) is no twin: its
    # pixels go back to its theme and the twins kept move up.
    kept = [t for t in twins
            if not np.array_equal(themes[t.twin].texture, themes[t.theme].texture)]
    if len(kept) < len(twins):
        moved = np.arange(256, dtype=np.uint8)
        moved[[t.twin for t in twins]] = [t.theme for t in twins]
        twins = renumbered(kept, n_themes)
        moved[[t.twin for t in kept]] = [t.twin for t in twins]
        split = moved[split]
        themes = made(split, twins)
    if not twins:
        return ThemeMapping(themes, mapping.lut, mapping.classes), split
    # Each theme at its whole class's gain, for a grid over its share with the twins.
    return ThemeMapping(themes, mapping.lut, mapping.classes, twins,
                        made(theme_labels, ())), split


def sample_themes(sample: RegionSample, classes: Sequence[int], themes: ThemesSpec = "auto",
                  *, patch: PatchOptions = PatchOptions(),
                  names: Mapping[int, str] | None = None,
                  detail: float | None = DETAIL_SIGMA,
                  calm: Sequence[CalmTwin] | None = None) -> ThemeMapping:
    """The themes of a region cut on its sample's windows side by side, as a tiled
    conversion and a whole photo in memory both take them (issue 34). ``calm``: as
    :func:`themes_and_cell`'s."""
    mapping = themes_and_cell(sample.rgb, sample.labels, classes, themes, cell=1, patch=patch,
                              names=names, detail=detail, calm=calm).mapping
    no_data = len(mapping.library) - 1 - len(mapping.calm)
    if not sample.gap or sample.no_data or no_data == 0 or int(mapping.lut[0]) != no_data:
        return mapping
    # The no-data theme (after the classes' themes; a library has none) was for the gaps
    # alone: label 0 maps to theme 0, as on a photo without no-data pixels, and the twins
    # after it move up one.
    lut = mapping.lut.copy()
    lut[0] = 0
    themes_left = [t for k, t in enumerate(mapping.library) if k != no_data]
    plain_left = None if mapping.plain is None else ThemeLibrary(
        t for k, t in enumerate(mapping.plain) if k != no_data)
    return ThemeMapping(ThemeLibrary(themes_left), lut, mapping.classes,
                        renumbered(mapping.calm, no_data), plain_left)


def cover_classes(sample: RegionSample, classes: Sequence[int], mapping: ThemeMapping,
                  grid: IndexGrid, size: tuple[int, int],
                  read: Callable[[list[tuple[int, int]]], RegionSample],
                  themes: ThemesSpec = "auto", *, patch: PatchOptions = PatchOptions(),
                  names: Mapping[int, str] | None = None,
                  detail: float | None = DETAIL_SIGMA) -> tuple[RegionSample, ThemeMapping]:
    """The region's sample and themes once its grid is known: a class the grid shows but
    the sample's windows missed had a flat placeholder theme, so windows move onto it
    (:func:`.region_sample.covering_sample`; ``read(covering)`` lays them out) and the
    themes are cut again, with the same class -> theme table. Unchanged otherwise."""
    if not cuts_themes(themes):
        return sample, mapping
    covered = covering_sample(sample, classes, mapping.lut, grid.indices, grid.cell, size, read)
    if covered is sample:
        return sample, mapping
    return covered, sample_themes(covered, classes, themes, patch=patch, names=names,
                                  detail=detail, calm=mapping.calm)


@dataclass(frozen=True)
class GridResult:
    """The vertex grid of a conversion and how well it keeps the labels.

    ``choice``: the agreement curve when the cell was chosen; ``agreement``: share of
    pixels whose theme the label view keeps; ``colour``: the colour map, if asked for;
    ``mapping``: the themes the grid indexes (the given ones, their calm twins dropped
    when the grid had no bytes for them).
    """

    grid: IndexGrid
    choice: CellChoice | None
    agreement: float
    colour: FittedColourMap | None
    mapping: ThemeMapping


def grid_and_colour(
    rgb: np.ndarray,
    theme_labels: np.ndarray,
    mapping: ThemeMapping,
    *,
    cell: str | int = "auto",
    target_agreement: float = 0.9,
    class_target: float = 0.0,
    candidates: Sequence[int] = DEFAULT_CELL_CANDIDATES,
    colour_map: ColourMapOptions | None = ColourMapOptions(),
    render: RenderOptions = RenderOptions(),
    progress: ProgressFn | None = None,
    choice: CellChoice | None = None,
    full_curve: bool = True,
    keep_specks: bool = True,
    grid_bpp: float | None = None,
    twin_labels: np.ndarray | None = None,
) -> GridResult:
    """Vote the (H, W) uint8 theme labels to a grid and fit the colour map to its render.

    ``colour_map`` None: the paper's pure rule. ``render``: how the project will be
    rendered (the map is fitted to it). ``choice``: with ``cell`` "auto", a
    :func:`choose_cell_size` result already made on these labels (made with the same
    ``keep_specks``), whose grid is taken when it carries one. ``keep_specks`` False:
    lone vertices take their neighbours' theme. ``grid_bpp``: the grid's share of a byte
    budget (:func:`grid_budget`; None: ``colour_map``'s), which ``mapping``'s calm twins
    must fit in (:func:`keep_calm`). ``twin_labels``: ``theme_labels`` split by
    ``mapping``'s twins (:attr:`Themed.twin_labels`), when known.
    """
    if cell != "auto" and (not isinstance(cell, int) or cell < 1):
        raise TerrathemeError(f"cell must be 'auto' or a positive integer, got {cell!r}")
    if cell != "auto":
        choice, size = None, (int(cell), int(cell))
    else:
        if choice is None:
            choice = choose_cell_size(theme_labels, target_agreement, candidates=candidates,
                                      class_target=class_target, progress=progress,
                                      full_curve=full_curve, keep_specks=keep_specks)
        size = choice.cell
    grid = choice.grid if choice is not None and choice.grid is not None else IndexGrid(
        vote_grid(theme_labels, size, keep_specks=keep_specks), size)
    score = choice.agreement if choice is not None else agreement(theme_labels, grid,
                                                                  max_pixels=1 << 22)
    if mapping.calm:
        # The class grid's vertices take their calm twins, if the grid's bytes allow them
        # (the choice then carries the grid).
        bits = grid_budget(colour_map, theme_labels.size) if grid_bpp is None else grid_bpp
        grid, mapping = calm_vertices(rgb, theme_labels, grid, mapping, bits,
                                      twin_labels=twin_labels)
        if choice is not None:
            choice = replace(choice, grid=grid, packed_bytes=packed_bytes(grid))
    fitted = None if colour_map is None else fit_colour_map(
        rgb, grid, mapping.library, colour_map, render,
        packed=choice.packed_bytes if choice is not None else None)
    return GridResult(grid, choice, score, fitted, mapping)


def keep_calm(grid: IndexGrid, mapping: ThemeMapping, grid_bpp: float | None,
              pixels: int) -> tuple[IndexGrid, ThemeMapping]:
    """``(grid, mapping)``, or both without the calm twins when the packed grid with them
    is over its share of a byte budget (``grid_bpp`` bits per photo pixel; None: no
    budget), or over the class grid's own bytes and ``TWIN_GRID_EXTRA`` of them where the
    class grid alone is over the share (small cells forced by the agreement floor): the
    bytes the twins cost come out of the colour map.
    Without them the themes are ``mapping.plain`` (each at its whole class's gain).
    ``grid`` may be the class grid alone (:func:`calm_grid` not yet run)."""
    if not mapping.calm or grid_bpp is None:
        return grid, mapping
    parents = IndexGrid(twin_parents(len(mapping.library), mapping.calm).astype(np.uint8)[
        grid.indices], grid.cell)
    share = max(grid_bpp * max(int(pixels), 1),
                packed_bytes(parents) * 8 * (1 + TWIN_GRID_EXTRA))
    if packed_bytes(grid) * 8 <= share:
        return grid, mapping
    n_themes = len(mapping.library) - len(mapping.calm)
    plain = mapping.plain if mapping.plain is not None else ThemeLibrary(
        list(mapping.library)[:n_themes])
    return parents, ThemeMapping(plain, mapping.lut, mapping.classes)


def calm_vertices(rgb: np.ndarray, theme_labels: np.ndarray, grid: IndexGrid,
                  mapping: ThemeMapping, grid_bpp: float | None, *,
                  twin_labels: np.ndarray | None = None) -> tuple[IndexGrid, ThemeMapping]:
    """The class ``grid`` (voted from the (H, W) uint8 ``theme_labels``) with ``mapping``'s
    calm twins at its vertices (:func:`calm_grid`) where :func:`keep_calm` keeps them, and
    ``mapping`` with them; both without them otherwise. ``twin_labels``: the labels split
    by the twins (:func:`detail_mapping`'s), else split here from ``rgb``."""
    if not mapping.calm:
        return grid, mapping
    if twin_labels is None:
        twin_labels = split_calm(theme_labels, mapping.calm, class_log_energy(
            rgb, theme_labels, [t.theme for t in mapping.calm]))
    return keep_calm(calm_grid(twin_labels, grid, mapping.calm), mapping, grid_bpp,
                     theme_labels.size)


def calm_grid(twin_labels: np.ndarray, grid: IndexGrid, twins: Sequence[CalmTwin]) -> IndexGrid:
    """``grid`` (voted from theme labels) with its vertices' calm twins
    (:func:`.calm.twin_vertices`), from a plain vote of the (H, W) uint8 ``twin_labels``
    (the labels split by ``twins``, :func:`split_calm`) at its cell, as each tile of a
    tiled conversion votes them."""
    votes = vote_grid(twin_labels, grid.cell, keep_specks=True)
    return IndexGrid(twin_vertices(grid.indices, votes, twins), grid.cell)


def fit_colour_map(rgb: np.ndarray, grid: IndexGrid, library: ThemeLibrary,
                   colour_map: ColourMapOptions = ColourMapOptions(),
                   render: RenderOptions = RenderOptions(), *,
                   packed: int | None = None) -> FittedColourMap:
    """The colour map fitted to the render it multiplies; a byte budget covers the packed
    grid too (``packed``: its bytes, when known)."""
    plain = render_cells(grid, library.textures, options=render)
    reserved = 0 if colour_map.target is not None else (
        packed_bytes(grid) if packed is None else packed)
    def predict(stored: np.ndarray, scale: int) -> Prediction | None:
        return grid_prediction(stored, grid, len(library), scale, colour_map.codec)

    return choose_colour_map(rgb, plain, colour_map, reserved=reserved, predict=predict)

