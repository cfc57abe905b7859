"""The layers of an edit document, what each must look like, and where the photo lies.

:class:`DocumentData` holds the texture's layers plus the editor-only confidence map
and kept prior; only :mod:`core.edit.changes` writes it. Layers set while editing are
checked by the project's own rule (:func:`core.model.layers.check_layer`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from terratheme.core.edit.uncertainty import KeptPrior
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.map_prediction import nearest_vertices
from terratheme.core.model.project import ThematicTexture
from terratheme.core.themes.library import ThemeLibrary


class Layer(Enum):
    """A layer of the document that an undoable change can paint or replace."""

    #: (gh+1, gw+1) uint8 theme index per grid vertex (painted, never replaced whole)
    GRID = "grid"
    #: (H, W) uint8 training strokes over the photo: class value = theme + 1, 0 = none
    SCRIBBLES = "scribbles"
    #: (H, W, C) uint8 orthophoto shown under the index map
    PHOTO = "photo"
    #: (H, W) float32 in [0, 1]: the last classification's confidence per photo pixel
    CONFIDENCE = "confidence"


def validate_confidence(confidence: object, photo: np.ndarray | None) -> np.ndarray:
    """A confidence map as a read-only (H, W) float32 array; TerrathemeError without a photo,
    at another size, or with values not finite in [0, 1].
    """
    conf = np.array(confidence, dtype=np.float32)
    if photo is None or conf.shape != photo.shape[:2]:
        have = "no photo" if photo is None else f"a {photo.shape[1]} x {photo.shape[0]} photo"
        raise TerrathemeError(f"a {conf.shape[::-1]} confidence map does not fit {have}")
    if conf.size and not (np.isfinite(conf).all() and conf.min() >= 0 and conf.max() <= 1):
        raise TerrathemeError("confidence map values must be finite and in [0, 1]")
    conf.setflags(write=False)
    return conf


def photo_extent(photo_shape: tuple[int, ...], grid: IndexGrid) -> tuple[float, float]:
    """``(width, height)`` in texels that a photo of ``photo_shape`` covers.

    1:1 from the origin (the converter's convention: the grid is rounded up
    to whole cells) when the photo is at most one cell smaller than the
    render in each direction; otherwise stretched over the whole render.
    """
    ph, pw = photo_shape[:2]
    w, h = grid.texture_size
    n, m = grid.cell
    if w - n < pw <= w and h - m < ph <= h:
        return float(pw), float(ph)
    return float(w), float(h)


def check_value(layer: Layer, value: object, n_themes: int) -> int:
    """Check a value to paint: a theme index on the grid, a class value in the scribbles.

    Scribble class value ``v`` marks theme ``v - 1``; 0 erases.
    """
    top = n_themes - 1 if layer is Layer.GRID else min(n_themes, 255)
    if not isinstance(value, int | np.integer) or not 0 <= int(value) <= top:
        what = "theme index" if layer is Layer.GRID else "scribble class value"
        raise TerrathemeError(f"{what} {value} is out of range 0..{top} "
                              f"(the library has {n_themes} themes)")
    return int(value)


def check_theme_name(library: ThemeLibrary, name: str, skip: int | None = None) -> None:
    """Refuse a theme name the library already has (case-insensitive), but for theme ``skip``."""
    taken = [n.lower() for i, n in enumerate(library.names) if i != skip]
    if name.lower() in taken:
        raise TerrathemeError(f"a theme called {name!r} is already in the library")


@dataclass(eq=False)
class DocumentData:
    """Everything an edit document holds; written only by :mod:`core.edit.changes`.

    ``texture`` (saved), and not saved: ``confidence`` (H, W) float32 read-only, the
    last classification's; ``kept_prior``; ``scribble_counts`` (256,) int64, pixels
    of each scribble value, kept current by every change so no scan is needed.
    """

    texture: ThematicTexture
    confidence: np.ndarray | None = None
    kept_prior: KeptPrior | None = None
    scribble_counts: np.ndarray = field(default_factory=lambda: np.zeros(256, np.int64))
    #: :meth:`colour_gains` once taken (None: not yet)
    theme_gains: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.recount_scribbles()
        self.colour_gains()

    def colour_gains(self) -> np.ndarray | None:
        """(256, 3) float32 mean colour-map gain over the map pixels nearest each theme's
        vertices (NaN: none; with detail themes, the theme's colour in the photo), taken
        from the map as opened or last replaced whole; None without a map."""
        cmap, grid = self.texture.colour_map, self.texture.grid
        if cmap is not None and self.theme_gains is None:
            (mh, mw), (vh, vw) = cmap.pixels.shape[:2], grid.indices.shape
            rows = nearest_vertices(mh, cmap.scale, grid.cell[1], vh)
            cols = nearest_vertices(mw, cmap.scale, grid.cell[0], vw)
            themes = grid.indices[rows[:, None], cols[None, :]].ravel()
            counts = np.bincount(themes, minlength=256)[:, None]
            sums = np.stack([np.bincount(themes, cmap.pixels[..., c].ravel().astype(float),
                                         minlength=256) for c in range(3)], axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                self.theme_gains = (sums / counts).astype(np.float32)
        return None if cmap is None else self.theme_gains

    def layer(self, which: Layer) -> np.ndarray | None:
        """The array of ``which`` (None when the document has no such layer)."""
        if which is Layer.GRID:
            return self.texture.grid.indices
        if which is Layer.CONFIDENCE:
            return self.confidence
        return getattr(self.texture, which.value)

    def set_layer(self, which: Layer, array: np.ndarray | None) -> None:
        """Put ``array`` in place of layer ``which`` (not the grid, which is painted)."""
        if which is Layer.GRID:
            raise TerrathemeError("the index grid is painted, never replaced whole")
        if which is Layer.CONFIDENCE:
            self.confidence = array
            return
        setattr(self.texture, which.value, array)
        if which is Layer.SCRIBBLES:
            self.recount_scribbles()

    def recount_scribbles(self) -> None:
        """Recount :attr:`scribble_counts` from the whole layer (after it was replaced)."""
        sc = self.texture.scribbles
        self.scribble_counts = (np.zeros(256, np.int64) if sc is None else
                                np.bincount(sc.ravel(), minlength=256).astype(np.int64))

    def scribble_classes(self) -> frozenset[int]:
        """Class values painted in the scribble layer (0 = unlabelled is not a class)."""
        return frozenset(int(v) for v in np.flatnonzero(self.scribble_counts[1:]) + 1)
