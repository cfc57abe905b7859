"""Matching classes of a photo to themes: one colour-and-texture rule for every caller.

A class and a theme compare by mean CIE Lab and the lightness's band-pass energy ``E``::

    cost = |Lab_class - Lab_theme| + TEXTURE_WEIGHT * |ln(E_class / E_theme)|

Used by the CLI's ``--themes name,name``, the editor, and to name cut themes after
the closest shipped one (never ``class 1``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.library import ThemeLibrary, distinct_names
from terratheme.core.themes.patch_search import (
    ClassStats,
    TextureStats,
    class_means,
    texture_stats,
)

#: Lab units per unit of |log energy ratio|
TEXTURE_WEIGHT = 6.0


@dataclass(frozen=True)
class Appearance:
    """Mean Lab colour, (3,) float, and band-pass energy of the lightness (``L / 100``)."""

    lab: np.ndarray
    energy: float


def class_appearances(stats: TextureStats | ClassStats, labels: np.ndarray | None,
                      classes: Sequence[int]) -> list[Appearance]:
    """Appearance of each class from the photo's statistics and (H, W) labels.

    ``stats``: the photo's :class:`TextureStats` with its ``labels``, or its
    :class:`ClassStats` (``labels`` None: taken already). A class absent from the
    labels gets mid-grey.
    """
    if isinstance(stats, ClassStats):
        lab, band, counts = stats.lab, stats.band, stats.counts
    else:
        means, counts = class_means(np.asarray(labels, np.uint8),
                                    np.concatenate([stats.lab, stats.band[:, :, None]], axis=2))
        lab, band = means[:, :3], means[:, 3]
    out = []
    for c in (int(c) for c in classes):
        if counts[c]:
            out.append(Appearance(lab[c], float(band[c])))
        else:
            out.append(Appearance(np.array([53.4, 0.0, 0.0]), 0.0))
    return out


@lru_cache(maxsize=32)
def _texture_appearance(data: bytes, shape: tuple[int, ...]) -> Appearance:
    """Appearance of a texture given as its bytes (cached: the shipped themes recur)."""
    st = texture_stats(np.frombuffer(data, np.uint8).reshape(shape))
    lab = st.lab.reshape(-1, 3).mean(axis=0)
    lab.setflags(write=False)
    return Appearance(lab, float(st.band.mean()))


def theme_appearances(library: ThemeLibrary) -> list[Appearance]:
    """Appearance of each theme's texture (by content, so a texture met before costs nothing)."""
    out = []
    for theme in library:
        tex = np.ascontiguousarray(theme.texture[:, :, :3], np.uint8)
        out.append(_texture_appearance(tex.tobytes(), tex.shape))
    return out


def match_cost(a: Sequence[Appearance], b: Sequence[Appearance]) -> np.ndarray:
    """(len(a), len(b)) cost of giving each class of ``a`` each theme of ``b``."""
    la = np.array([x.lab for x in a]).reshape(-1, 3)
    lb = np.array([x.lab for x in b]).reshape(-1, 3)
    ea = np.log(np.array([x.energy for x in a]) + 1e-6)
    eb = np.log(np.array([x.energy for x in b]) + 1e-6)
    return (np.linalg.norm(la[:, None] - lb[None], axis=2)
            + TEXTURE_WEIGHT * np.abs(ea[:, None] - eb[None]))


def match_classes(classes: Sequence[Appearance], themes: Sequence[Appearance], *,
                  distinct: bool) -> list[int]:
    """The theme index of each class: distinct themes by least total cost, or each its nearest.

    Raises :class:`TerrathemeError` when ``distinct`` with fewer themes than classes.
    """
    if not themes:
        raise TerrathemeError("no themes to match the classes to")
    cost = match_cost(classes, themes)
    if not distinct:
        return [int(k) for k in np.argmin(cost, axis=1)]
    if len(themes) < len(classes):
        raise TerrathemeError(f"{len(classes)} classes but only {len(themes)} themes to give "
                              "them distinct themes")
    # scipy.optimize takes 0.7 s to import: only the distinct assignment pays for it.
    from scipy.optimize import linear_sum_assignment

    rows, cols = linear_sum_assignment(cost)
    out = [0] * len(classes)
    for r, c in zip(rows, cols, strict=True):
        out[int(r)] = int(c)
    return out


def shipped_names(appearances: Sequence[Appearance], library: ThemeLibrary,
                  looks: Sequence[tuple[str, Appearance]] = ()) -> list[str]:
    """A name for each class after its closest theme of ``library`` ("water", "water 2", ...).

    ``looks``: more ``(theme name, appearance)`` exemplars (:func:`read_looks`) beside the
    textures; those of names not in ``library`` are skipped.
    """
    names = list(library.names)
    owners = list(range(len(names)))
    exemplars = theme_appearances(library)
    for name, look in looks:
        if name in names:
            owners.append(names.index(name))
            exemplars.append(look)
    nearest = match_classes(appearances, exemplars, distinct=False)
    return distinct_names(names[owners[i]] for i in nearest)
