"""Themes for a classified photo: cut from the photo itself, or shipped themes by name.

*Cut from the photo* (design.md §2-3, "themes cut from the photo itself and
made tileable"): for every class, the window whose texture statistics are
closest to the class's (band-pass energy, Lab spread and mean;
:mod:`core.themes.patch_search`) is cut out, the few pixels of other classes
in it are filled from the class's own pixels of the window (shifted copies),
and it is made tileable with :func:`core.themes.tileable.make_tileable`. A
tile that would visibly repeat (:func:`core.themes.quality.repeat_score` or
:func:`core.themes.quality.landmark_score` over their limits) is replaced by
the next best window. A class with no window of ``min_size`` inside it (a
few scattered pixels, or a photo smaller than ``min_size``) gets a flat theme
of its mean colour, and says so in ``Theme.source``.

*Shipped themes by name*: classes map to themes of
:func:`core.themes.library.shipped_theme_library`, either explicitly (``{class:
name}``) or by appearance: the assignment of classes to distinct named themes
of least total colour-and-texture cost (:mod:`core.themes.matching`, the rule
the editor uses too). Themes cut from the photo are named after their closest
shipped theme.

Both return a :class:`ThemeMapping`: the library plus the 256-entry table
class value -> theme index used by :func:`core.convert.labels_to_grid.labels_to_grid`.
Label 0 (no data: transparent pixels) gets a theme of its own, ``no data``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from core.errors import TerrathemeError
from core.themes.library import (
    Theme,
    ThemeLibrary,
    distinct_names,
    flat_theme,
    shipped_theme_library,
)
from core.themes.looks import read_looks
from core.themes.matching import (
    class_appearances,
    match_classes,
    shipped_names,
    theme_appearances,
)
from core.themes.patch_search import (
    INTERIOR,
    ClassTarget,
    PatchOptions,
    WindowStats,
    best_windows,
    class_means,
    class_targets,
    find_patch,
    texture_stats,
)
from core.themes.quality import (
    LANDMARK_CONTRAST,
    LANDMARK_SIZE,
    landmark_mask,
    landmark_score,
    repeat_score,
)
from core.themes.quilt import QuiltOptions, quilt_tileable
from core.themes.tileable import make_tileable

NO_DATA_NAME = "no data"
NO_DATA_COLOUR = (0, 0, 0)


@dataclass(frozen=True)
class ThemeMapping:
    """A theme library for a classification and the class -> theme index table.

    Attributes
    ----------
    library : ThemeLibrary
    lut : (256,) uint8 ndarray
        ``lut[class_value]`` is the theme index of that class.
    classes : tuple of int
        The class values mapped, in theme order.
    """
    library: ThemeLibrary
    lut: np.ndarray
    classes: tuple[int, ...]


def _check(photo: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    rgb = np.asarray(photo)
    lab = np.asarray(labels)
    if rgb.ndim != 3 or rgb.shape[2] < 3 or rgb.dtype != np.uint8:
        raise TerrathemeError(f"photo must be (H, W, 3) uint8 RGB, got {rgb.shape} {rgb.dtype}")
    if lab.shape != rgb.shape[:2]:
        raise TerrathemeError(
            f"labels {lab.shape[1]} x {lab.shape[0]} do not match the "
            f"{rgb.shape[1]} x {rgb.shape[0]} photo"
        )
    return np.ascontiguousarray(rgb[:, :, :3]), lab.astype(np.uint8, copy=False)


def fill_from_class(patch: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Fill the pixels of ``patch`` outside ``keep`` from shifted copies of its kept pixels.

    Parameters
    ----------
    patch : (s, s, 3) uint8 ndarray
    keep : (s, s) bool ndarray
        The class's own pixels (at least one).

    Returns
    -------
    (s, s, 3) uint8 ndarray
        Every pixel a pixel of the class: holes take the texel at the smallest
        circular shift (of a fixed list, nearest first) that lands on a kept one.
    """
    out = patch.copy()
    have = keep.copy()
    s = patch.shape[0]
    steps = sorted({(dy, dx) for dy in range(-s // 2, s // 2 + 1, max(1, s // 16))
                    for dx in range(-s // 2, s // 2 + 1, max(1, s // 16)) if (dy, dx) != (0, 0)},
                   key=lambda d: (d[0] ** 2 + d[1] ** 2, d))
    for dy, dx in steps:
        if have.all():
            break
        # Holes take this shift's texel where the shifted pixel is the class's own.
        src_keep = np.roll(keep, (dy, dx), axis=(0, 1))
        take = ~have & src_keep
        if take.any():
            out[take] = np.roll(patch, (dy, dx), axis=(0, 1))[take]
            have |= take
    if not have.all():
        out[~have] = patch[keep].reshape(-1, 3).mean(axis=0).astype(np.uint8)
    return out


#: an object stands out of its texture when it passes this many luma spreads (and 20 levels)
OBJECT_SPREADS = 4.0


def lone_objects(window: np.ndarray) -> np.ndarray:
    """Pixels of objects that stand out of a patch's texture (a lone building in water).

    Dark or bright features narrower than
    :data:`core.themes.quality.LANDMARK_SIZE` whose contrast passes
    ``OBJECT_SPREADS`` times the patch's own luma spread
    (:func:`core.themes.quality.landmark_mask`), grown by two pixels. Tiled,
    such an object repeats on a grid the eye picks out at once; in a busy
    texture (town) the threshold rises with the spread, so its streets stay.

    Returns
    -------
    (s, s) bool ndarray
    """
    lum = window.astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
    spread = float(np.std(lum - cv2.GaussianBlur(lum, (0, 0), LANDMARK_SIZE / 4)))
    dark, bright = landmark_mask(window, periodic=False,
                                 contrast=max(LANDMARK_CONTRAST, OBJECT_SPREADS * spread))
    grown = cv2.dilate((dark | bright).astype(np.uint8), np.ones((5, 5), np.uint8))
    return grown.astype(bool)


def class_interior(mask: np.ndarray, x: int, y: int, s: int) -> np.ndarray:
    """The class's pixels of an ``s x s`` window at least ``INTERIOR`` pixels from its border.

    Pixels along a class border are blends of the two sides (the dark rim of a
    shore on sand); cut into a theme they repeat as a line once per tile, and
    the render draws the border itself. The border is the class region's own,
    not the window's: the mask is read ``INTERIOR`` pixels beyond the window.

    Parameters
    ----------
    mask : (H, W) bool ndarray
        The class region in the photo.
    x, y, s : the window

    Returns
    -------
    (s, s) bool ndarray
    """
    h, w = mask.shape
    r = INTERIOR
    x0, y0, x1, y1 = max(0, x - r), max(0, y - r), min(w, x + s + r), min(h, y + s + r)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    # Outside the photo the class goes on (replicated border): the photo's edge is no border.
    inner = cv2.erode(mask[y0:y1, x0:x1].astype(np.uint8), kernel,
                      borderType=cv2.BORDER_REPLICATE)
    return inner[y - y0 : y - y0 + s, x - x0 : x - x0 + s].astype(bool)


#: a tile repeating more than this (repeat_score) or holding a larger landmark is replaced
REPEAT_LIMIT = 0.3
LANDMARK_LIMIT = 0.04
#: windows tried per class before the best rejected one is kept
PATCH_TRIES = 3
#: classes whose tiles are cut at once (each tile depends on its class alone)
TILE_THREADS = 2


def _class_tile(rgb: np.ndarray, mask: np.ndarray, windows: WindowStats, target: ClassTarget,
                options: PatchOptions) -> tuple[np.ndarray, str] | None:
    """The tileable patch of one class and where it came from, or None when none fits."""
    tried: list[tuple[int, int, int]] = []
    fallback = None
    for _ in range(PATCH_TRIES):
        found = find_patch(windows, mask, options, exclude=tried, target=target)
        if found is None:
            break
        x, y, s = found
        tried.append(found)
        # Other classes' pixels, the class's border rim and lone objects that would
        # repeat once per tile are filled from the class's own pixels of the window.
        window = rgb[y : y + s, x : x + s]
        inner = class_interior(mask, x, y, s)
        if not inner.any():
            inner = mask[y : y + s, x : x + s]
        # Objects are found with the other classes painted in the class's median colour:
        # a dark rim left along a shore is then a line on sand, not the edge of the water.
        seen = window.copy()
        seen[~inner] = np.median(window[inner], axis=0).astype(np.uint8)
        keep = inner & ~lone_objects(seen)
        cut = window if keep.all() else fill_from_class(window, keep if keep.any() else inner)
        tile = make_tileable(cut)
        source = f"photo patch x={x} y={y} size={s}"
        if repeat_score(tile) <= REPEAT_LIMIT and landmark_score(tile) <= LANDMARK_LIMIT:
            return tile, source
        fallback = fallback or (tile, source + " (repeats)")
    if fallback is None or not options.quilt:
        return fallback
    # No window tiles without repeating: quilt the theme from many small blocks instead,
    # when that repeats less.
    # The blocks: the class's windows whose texture statistics are closest to its own.
    quilting = QuiltOptions(size=options.size)
    corners = best_windows(windows, mask, quilting.block, quilting.candidates, options,
                           spacing=quilting.block // 6, target=target)
    quilt = quilt_tileable(rgb, corners, quilting)
    if quilt is None:
        return fallback
    tile = make_tileable(quilt)
    if repeat_score(tile) >= repeat_score(fallback[0]):
        return fallback
    return tile, f"quilted from {quilting.steps() ** 2} blocks of the class"


def _lut_for(classes: Sequence[int], has_no_data: bool) -> np.ndarray:
    lut = np.zeros(256, np.uint8)
    for k, c in enumerate(classes):
        lut[c] = k
    if has_no_data:
        lut[0] = len(classes)
    return lut


def _present_classes(labels: np.ndarray, classes: Sequence[int] | None) -> list[int]:
    found = [int(c) for c in np.flatnonzero(np.bincount(labels.ravel(), minlength=256)) if c]
    if classes is None:
        return found
    return sorted({int(c) for c in classes if int(c) != 0} | set(found))


def photo_theme_lut(labels: np.ndarray, classes: Sequence[int] | None = None) -> np.ndarray:
    """The class -> theme index table :func:`themes_from_photo` gives, without cutting a theme.

    It depends on the classes only (theme ``k`` is the ``k``-th class, then
    ``no data``), so a caller can use the theme labels while the themes are cut.

    Parameters
    ----------
    labels : (H, W) uint8 ndarray
    classes : sequence of int, optional
        As :func:`themes_from_photo`.

    Returns
    -------
    lut : (256,) uint8 ndarray
    """
    labels = np.asarray(labels)
    return _lut_for(_present_classes(labels, classes), bool((labels == 0).any()))


def themes_from_photo(
    photo: np.ndarray,
    labels: np.ndarray,
    *,
    classes: Sequence[int] | None = None,
    names: Mapping[int, str] | None = None,
    options: PatchOptions = PatchOptions(),
) -> ThemeMapping:
    """One tileable theme per class, cut from the photo where its texture matches the class.

    Parameters
    ----------
    photo : (H, W, 3) uint8 ndarray
    labels : (H, W) uint8 ndarray
        Class values; 0 = no data.
    classes : sequence of int, optional
        Class values to make themes for (default: those present, ascending).
        A class absent from the labels gets a mid-grey flat theme.
    names : {class: name}, optional
        Theme names (a legend's, :mod:`core.io.legend`); a class without one
        is named after its closest shipped theme
        (:func:`core.themes.matching.shipped_names`), made distinct from the given names.
    options : PatchOptions

    Returns
    -------
    ThemeMapping
    """
    rgb, labels = _check(photo, labels)
    wanted = _present_classes(labels, classes)
    stats = texture_stats(rgb, options)
    windows = WindowStats(stats)
    names = {int(c): n for c, n in (names or {}).items()}
    unnamed = [c for c in wanted if c not in names]
    if unnamed:
        # Named after the closest shipped theme (water, sand, grass, ...), never "class 1".
        # A class takes the name of its nearest look: theme textures and aerial exemplars.
        appearances = class_appearances(stats, labels, unnamed)
        named = shipped_names(appearances, shipped_theme_library(), read_looks())
        names.update(zip(unnamed, named, strict=True))
    # Given names first, so a guessed name that repeats one takes the number.
    order = sorted(wanted, key=lambda c: c in unnamed)
    names = dict(zip(order, distinct_names(names[c] for c in order), strict=True))
    # Every class's colour and texture statistics in one pass over the photo.
    colours, counts = class_means(labels, rgb)
    targets = class_targets(stats, labels, [c for c in wanted if counts[c]])
    # The classes' tiles on two threads (OpenCV, numpy and the seam kernels release the GIL).
    with ThreadPoolExecutor(max_workers=TILE_THREADS) as pool:
        tiles = dict(zip(targets, pool.map(
            lambda c: _class_tile(rgb, labels == c, windows, targets[c], options), targets),
            strict=True))
    themes = []
    for c in wanted:
        name = names[c]
        if not counts[c]:
            themes.append(flat_theme(name, (128, 128, 128)).with_(source="class absent from photo"))
            continue
        colour = tuple(int(v) for v in np.clip(np.rint(colours[c]), 0, 255))
        found = tiles[c]
        if found is None:
            theme = flat_theme(name, colour).with_(
                source=f"flat mean colour (no {options.min_size}px patch inside the class)"
            )
        else:
            theme = Theme(name, colour, found[0], source=found[1])
        themes.append(theme)
    has_no_data = bool((labels == 0).any())
    if has_no_data:
        # A class a legend calls "no data" keeps its name; the transparent pixels' is numbered.
        no_data = distinct_names([*names.values(), NO_DATA_NAME])[-1]
        themes.append(flat_theme(no_data, NO_DATA_COLOUR).with_(source="transparent pixels"))
    return ThemeMapping(ThemeLibrary(themes), _lut_for(wanted, has_no_data), tuple(wanted))


def themes_by_name(
    photo: np.ndarray,
    labels: np.ndarray,
    names: Sequence[str] | Mapping[int, str],
    library: ThemeLibrary | None = None,
) -> ThemeMapping:
    """Map classes to named themes of a library (default: the shipped themes).

    Parameters
    ----------
    photo : (H, W, 3) uint8 ndarray
    labels : (H, W) uint8 ndarray
        Class values; 0 = no data.
    names : sequence of str or {class: name}
        A mapping is taken as given. A sequence is assigned by colour: each
        class present goes to a distinct named theme, the assignment that
        minimises the summed colour-and-texture cost of
        :func:`core.themes.matching.match_classes`; there must be at least as
        many names as classes.
    library : ThemeLibrary, optional

    Returns
    -------
    ThemeMapping
        The library holds the used themes in class order.
    """

    rgb, labels = _check(photo, labels)
    source = library if library is not None else shipped_theme_library()
    classes = _present_classes(labels, None)
    if isinstance(names, Mapping):
        chosen = {int(c): source[source.index_of(n)] for c, n in names.items()}
        missing = [c for c in classes if c not in chosen]
        if missing:
            raise TerrathemeError(f"classes {missing} have no theme name (given: {dict(names)})")
        classes = sorted(chosen)
    else:
        picks = [source[source.index_of(n)] for n in names]
        if len({t.name for t in picks}) != len(picks):
            raise TerrathemeError(f"theme names repeat: {list(names)}")
        if len(picks) < len(classes):
            raise TerrathemeError(
                f"the photo has {len(classes)} classes but only {len(picks)} theme names were "
                f"given ({', '.join(names)})"
            )
        # One rule (core.themes.matching): colour and texture, distinct themes.
        looks = class_appearances(texture_stats(rgb), labels, classes)
        picked = match_classes(looks, theme_appearances(ThemeLibrary(picks)), distinct=True)
        chosen = {c: picks[k] for c, k in zip(classes, picked, strict=True)}
    # One theme per distinct name (two classes may share one), in class order.
    themes: list[Theme] = []
    lut = np.zeros(256, np.uint8)
    for c in classes:
        names_so_far = [t.name for t in themes]
        if chosen[c].name not in names_so_far:
            themes.append(chosen[c])
        lut[c] = [t.name for t in themes].index(chosen[c].name)
    if (labels == 0).any():
        lut[0] = len(themes)
        themes.append(flat_theme(NO_DATA_NAME, NO_DATA_COLOUR).with_(source="transparent pixels"))
    return ThemeMapping(ThemeLibrary(themes), lut, tuple(classes))
