"""Themes for a classified photo: cut from the photo itself, or shipped themes by name.

*Cut from the photo* (DESIGN.md §4, "themes cut from the photo itself and
made tileable"): for every class, the square window that lies (almost)
entirely inside the class region and whose pixels lie closest, in mean
squared CIE Lab distance, to the class's mean colour is cut out and made
tileable with
:func:`core.themes.tileable.make_tileable`. That distance is the window's colour
variance plus the squared distance of its mean from the class mean, so the
patch is both homogeneous (least texture energy, no mixture with a
neighbouring class) and representative: variance alone prefers the darkest,
flattest corner of a class (deep water, shadow), whose colour is not the
class's. Window means and variances at every
position come from box filters (``cv2.boxFilter``), so the search costs a few
passes over the photo per size tried. Sizes shrink from ``PatchOptions.size``
until a window fits; a class with no window of ``min_size`` inside it (a few
scattered pixels, or a photo smaller than ``min_size``) gets a flat theme of
its mean colour, and says so in ``Theme.source``.

*Shipped themes by name*: classes map to themes of
:func:`core.themes.library.shipped_theme_library`, either explicitly (``{class:
name}``) or by colour: the assignment of classes to the named themes that
minimises the total Lab distance between class mean colours and theme mean
colours (``scipy.optimize.linear_sum_assignment``).

Both return a :class:`ThemeMapping`: the library plus the 256-entry table
class value -> theme index used by :func:`core.convert.labels_to_grid.labels_to_grid`.
Label 0 (no data: transparent pixels) gets a theme of its own, ``no data``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from core.errors import TerrathemeError
from core.themes.library import Theme, ThemeLibrary, flat_theme, shipped_theme_library
from core.themes.tileable import make_tileable

NO_DATA_NAME = "no data"
NO_DATA_COLOUR = (0, 0, 0)


@dataclass(frozen=True)
class PatchOptions:
    """How theme patches are searched.

    Attributes
    ----------
    size : int
        Largest patch side tried (pixels).
    min_size : int
        Smallest patch side tried; below it the class gets a flat theme.
    inside : float
        Share of the patch's pixels that must carry the class.
    representative : bool
        True: score windows by the mean squared Lab distance of their pixels
        from the class's mean colour. False: by their Lab variance alone (the
        most homogeneous window, whatever its colour).
    """
    size: int = 128
    min_size: int = 16
    inside: float = 0.97
    representative: bool = True


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


def _lab(photo: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 CIE Lab of an (H, W, 3) uint8 sRGB photo (OpenCV's conversion)."""
    return cv2.cvtColor(photo.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)


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


def find_patch(
    lab: np.ndarray, mask: np.ndarray, options: PatchOptions = PatchOptions()
) -> tuple[int, int, int] | None:
    """The most homogeneous square window inside a class region.

    Parameters
    ----------
    lab : (H, W, 3) float32 ndarray
        The photo in CIE Lab.
    mask : (H, W) bool ndarray
        The class region.
    options : PatchOptions

    Returns
    -------
    (x, y, size) or None
        Top-left corner and side of the window with at least ``options.inside``
        of its pixels in the class and the lowest score (see
        :class:`PatchOptions`); ``None`` when not even a ``min_size`` window
        fits.
    """
    h, w = mask.shape
    m = mask.astype(np.float32)
    lab2 = lab * lab
    # The class's mean Lab colour, which representative windows stay close to.
    target = None
    if options.representative and mask.any():
        target = lab[mask].reshape(-1, 3).mean(axis=0)
    # Sizes tried: from the largest that fits down to min_size, shrinking by 3/4.
    size = min(options.size, h, w)
    sizes = []
    while size >= options.min_size:
        sizes.append(size)
        size = size * 3 // 4
    for size in sizes:
        # Box means of the mask, of Lab and of Lab^2 at every window position (top-left anchor).
        k = (size, size)
        cover = cv2.boxFilter(m, -1, k, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
        mean = cv2.boxFilter(lab, -1, k, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
        sq = cv2.boxFilter(lab2, -1, k, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
        var = (sq - mean * mean).sum(axis=2)
        # Mean squared distance to the class colour = variance + |window mean - class mean|^2.
        if target is not None:
            var = var + ((mean - target) ** 2).sum(axis=2)
        # Only windows inside the photo whose pixels are (almost) all in the class.
        ok = np.zeros((h, w), bool)
        ok[: h - size + 1, : w - size + 1] = True
        ok &= cover >= options.inside - 1e-6
        if ok.any():
            score = np.where(ok, var, np.inf)
            y, x = np.unravel_index(int(np.argmin(score)), score.shape)
            return int(x), int(y), int(size)
    return None


def _mean_colour(photo: np.ndarray, mask: np.ndarray) -> tuple[int, int, int]:
    mean = photo[mask].reshape(-1, 3).mean(axis=0)
    return tuple(int(v) for v in np.clip(np.rint(mean), 0, 255))


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


def themes_from_photo(
    photo: np.ndarray,
    labels: np.ndarray,
    *,
    classes: Sequence[int] | None = None,
    names: Mapping[int, str] | None = None,
    options: PatchOptions = PatchOptions(),
) -> ThemeMapping:
    """One tileable theme per class, cut from the photo's most homogeneous patch of that class.

    Parameters
    ----------
    photo : (H, W, 3) uint8 ndarray
    labels : (H, W) uint8 ndarray
        Class values; 0 = no data.
    classes : sequence of int, optional
        Class values to make themes for (default: those present, ascending).
        A class absent from the labels gets a mid-grey flat theme.
    names : {class: name}, optional
        Theme names; default ``"class <k>"``.
    options : PatchOptions

    Returns
    -------
    ThemeMapping
    """
    rgb, labels = _check(photo, labels)
    wanted = _present_classes(labels, classes)
    lab = _lab(rgb)
    themes = []
    for c in wanted:
        name = (names or {}).get(c, f"class {c}")
        mask = labels == c
        if not mask.any():
            themes.append(flat_theme(name, (128, 128, 128)).with_(source="class absent from photo"))
            continue
        colour = _mean_colour(rgb, mask)
        found = find_patch(lab, mask, options)
        if found is None:
            theme = flat_theme(name, colour).with_(
                source=f"flat mean colour (no {options.min_size}px patch inside the class)"
            )
        else:
            x, y, s = found
            tile = make_tileable(rgb[y : y + s, x : x + s])
            theme = Theme(name, colour, tile, source=f"photo patch x={x} y={y} size={s}")
        themes.append(theme)
    has_no_data = bool((labels == 0).any())
    if has_no_data:
        themes.append(flat_theme(NO_DATA_NAME, NO_DATA_COLOUR).with_(source="transparent pixels"))
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
        minimises the summed Lab distance between class and theme mean
        colours; there must be at least as many names as classes.
    library : ThemeLibrary, optional

    Returns
    -------
    ThemeMapping
        The library holds the used themes in class order.
    """
    from scipy.optimize import linear_sum_assignment


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
        # Class and theme mean colours in Lab; assign by least total colour distance.
        cls_lab = np.array([_lab(np.array([[_mean_colour(rgb, labels == c)]], np.uint8))[0, 0]
                            for c in classes]).reshape(-1, 3)
        thm_lab = np.array([_lab(t.texture).reshape(-1, 3).mean(axis=0) for t in picks])
        cost = np.linalg.norm(cls_lab[:, None, :] - thm_lab[None, :, :], axis=2)
        rows, cols = linear_sum_assignment(cost)
        chosen = {classes[r]: picks[c] for r, c in zip(rows, cols, strict=True)}
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
