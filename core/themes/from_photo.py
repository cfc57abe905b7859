"""Themes for a classified photo: cut from the photo itself, or shipped themes by name.

Cut (design.md §2-3): per class, the window whose texture is closest to the class's,
cleaned (:mod:`.cut_mask`) and made tileable; if it repeats, the next window, then a
quilt; a class with no window of ``min_size`` gets a flat theme. By name: classes map
to shipped themes, given or matched by appearance (:mod:`.matching`). Both return a
:class:`ThemeMapping`; label 0 (no data) gets a theme of its own.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.calm import CalmTwin
from terratheme.core.themes.cut_mask import cut_window
from terratheme.core.themes.library import (
    Theme,
    ThemeLibrary,
    distinct_names,
    flat_theme,
    shipped_theme_library,
)
from terratheme.core.themes.looks import read_looks
from terratheme.core.themes.matching import (
    class_appearances,
    match_classes,
    shipped_names,
    theme_appearances,
)
from terratheme.core.themes.patch_search import (
    ClassTarget,
    PatchOptions,
    WindowStats,
    best_windows,
    class_stats,
    class_windows,
    find_patch,
    texture_stats,
)
from terratheme.core.themes.quality import tiles_unseen
from terratheme.core.themes.quilt import QuiltOptions, quilt_tileable
from terratheme.core.themes.tileable import make_tileable

NO_DATA_NAME = "no data"
NO_DATA_COLOUR = (0, 0, 0)


@dataclass(frozen=True)
class ThemeMapping:
    """A theme library for a classification and the class -> theme index table.

    ``lut``: (256,) uint8, ``lut[class_value]`` the theme index; ``classes``: the class
    values mapped, in theme order; ``calm``: the calm twins that split the table's themes
    by the photo's local detail (:mod:`.calm`), appended after them in ``library``;
    ``plain``: with twins, the table's themes as made without them (a detail theme at its
    whole class's gain, not its busy part's), for a grid that cannot afford the twins.
    """
    library: ThemeLibrary
    lut: np.ndarray
    classes: tuple[int, ...]
    calm: tuple[CalmTwin, ...] = ()
    plain: ThemeLibrary | None = None


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


#: windows tried per class before the best rejected one is kept
PATCH_TRIES = 3
#: classes whose tiles are cut at once (each tile depends on its class alone)
TILE_THREADS = 2


def _class_tile(rgb: np.ndarray, mask: np.ndarray, interior: np.ndarray, windows: WindowStats,
                target: ClassTarget, options: PatchOptions) -> tuple[np.ndarray, str] | None:
    """The tileable patch of one class and where it came from, or None when none fits."""
    # The class's windows scored once; each try skips those near the windows tried.
    scored = class_windows(windows, mask, options, target)
    tried: list[tuple[int, int, int]] = []
    fallback, fallback_repeat = None, 0.0
    for _ in range(PATCH_TRIES):
        found = find_patch(scored, exclude=tried)
        if found is None:
            break
        x, y, s = found
        tried.append(found)
        # Other classes, the class's rim and lone objects filled from its own pixels.
        cut = cut_window(rgb, mask, x, y, s, interior)
        tile = make_tileable(cut)
        source = f"photo patch x={x} y={y} size={s}"
        repeat, unseen = tiles_unseen(tile)
        if unseen:
            return tile, source
        if fallback is None:
            fallback, fallback_repeat = (tile, source + " (repeats)"), repeat
    if fallback is None or not options.quilt:
        return fallback
    # No window tiles without repeating: quilt the theme from many small blocks instead,
    # when that repeats less.
    # The blocks: the class's windows whose texture statistics are closest to its own.
    quilting = QuiltOptions(size=options.size)
    corners = best_windows(scored, quilting.block, quilting.candidates,
                           spacing=quilting.block // 6)
    quilt = quilt_tileable(rgb, corners, quilting)
    if quilt is None:
        return fallback
    tile = make_tileable(quilt)
    # The quilt unless it repeats more than the best window and fails a limit too.
    repeat, unseen = tiles_unseen(tile)
    if not unseen and repeat >= fallback_repeat:
        return fallback
    return tile, f"quilted from {quilting.steps() ** 2} blocks of the class"


def _lut_for(classes: Sequence[int], has_no_data: bool) -> np.ndarray:
    lut = np.zeros(256, np.uint8)
    for k, c in enumerate(classes):
        lut[c] = k
    if has_no_data:
        lut[0] = len(classes)
    return lut


def _wanted(counts: np.ndarray, classes: Sequence[int] | None) -> list[int]:
    """The classes given themes: those with pixels in (256,) ``counts``, and ``classes``."""
    found = [int(c) for c in np.flatnonzero(counts) if c]
    if classes is None:
        return found
    return sorted({int(c) for c in classes if int(c) != 0} | set(found))


def photo_theme_lut(labels: np.ndarray, classes: Sequence[int] | None = None) -> np.ndarray:
    """(256,) uint8: :func:`themes_from_photo`'s class -> theme table, without cutting."""
    counts = np.bincount(np.asarray(labels).ravel(), minlength=256)
    return _lut_for(_wanted(counts, classes), bool(counts[0]))


def themes_from_photo(
    photo: np.ndarray,
    labels: np.ndarray,
    *,
    classes: Sequence[int] | None = None,
    names: Mapping[int, str] | None = None,
    options: PatchOptions = PatchOptions(),
) -> ThemeMapping:
    """One tileable theme per class, cut from the photo where its texture matches the class.

    ``photo`` (H, W, 3) uint8; ``labels`` (H, W) uint8 class values, 0 = no data.
    ``classes`` (default: those present) may name absent ones, which get mid-grey; ``names``
    (a legend's) name themes, others take their closest shipped theme's name.
    """
    rgb, labels = _check(photo, labels)
    # Every class's colour and texture statistics, taken once.
    stats = class_stats(rgb, labels, options)
    windows, colours, counts = stats.windows, stats.colour, stats.counts
    wanted = _wanted(counts, classes)
    names = {int(c): n for c, n in (names or {}).items()}
    unnamed = [c for c in wanted if c not in names]
    if unnamed:
        # Named after the closest shipped theme (water, sand, grass, ...), never "class 1".
        # A class takes the name of its nearest look: theme textures and aerial exemplars.
        appearances = class_appearances(stats, None, unnamed)
        named = shipped_names(appearances, shipped_theme_library(), read_looks())
        names.update(zip(unnamed, named, strict=True))
    # Given names first, so a guessed name that repeats one takes the number.
    order = sorted(wanted, key=lambda c: c in unnamed)
    names = dict(zip(order, distinct_names(names[c] for c in order), strict=True))
    targets = {c: stats.targets[c] for c in wanted if counts[c]}
    # The classes' tiles on two threads (OpenCV, numpy and the seam kernels release the GIL).
    with ThreadPoolExecutor(max_workers=TILE_THREADS) as pool:
        tiles = dict(zip(targets, pool.map(
            lambda c: _class_tile(rgb, labels == c, stats.interior == c, windows, targets[c],
                                  options), targets),
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
    has_no_data = bool(counts[0])
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

    ``names``: a mapping is taken as given; a sequence (at least one name per class) is
    assigned to distinct themes by least colour-and-texture cost (:func:`match_classes`).
    The returned library holds the used themes in class order.
    """

    rgb, labels = _check(photo, labels)
    source = library if library is not None else shipped_theme_library()
    classes = _wanted(np.bincount(labels.ravel(), minlength=256), None)
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
