"""``pack(image)``: the packing algorithm of seed section 2.2, one layer or a grid of tiles."""

from __future__ import annotations

import enum
from collections.abc import Callable

import numpy as np
from terratheme.core.curves.scan import scan_runs
from terratheme.core.curves.square import Curve
from terratheme.core.errors import OptionError, TerrathemeError
from terratheme.core.packing import palette as _palette
from terratheme.core.packing.layer import PackedLayer
from terratheme.core.packing.palette import (
    MAX_COLOURS,
    PaletteReport,
    check_image,
    colour_keys,
    image_runs,
)
from terratheme.core.packing.tiled import TiledLayer, needs_tiles
from terratheme.core.packing.tiled_format import MAX_TILED_SIDE

ProgressFn = Callable[[int, int], None]


class CurveChoice(enum.Enum):
    """Which curve to scan with; ``AUTO`` keeps whichever gives fewer runs (per tile)."""

    HILBERT = "hilbert"
    MORTON = "morton"
    AUTO = "auto"

    @property
    def curves(self) -> list[Curve]:
        """The curves to try."""
        return [Curve.HILBERT, Curve.MORTON] if self is CurveChoice.AUTO else [Curve[self.name]]

    @classmethod
    def parse(cls, curve: str | CurveChoice | Curve) -> CurveChoice:
        """A choice from ``"hilbert"`` / ``"morton"`` / ``"auto"``, a Curve or a choice."""
        if isinstance(curve, CurveChoice):
            return curve
        if isinstance(curve, Curve):
            return cls(curve.name.lower())
        try:
            return cls(str(curve).strip().lower())
        except ValueError:
            raise TerrathemeError(
                f"unknown curve {curve!r}: use 'hilbert', 'morton' or 'auto'") from None


class TilePalette:
    """Palette indices of run keys across tiles; colours in order of first appearance.

    ``identity``: keys are the indices themselves (an index image); else keys hold the
    ``channels`` samples of ``dtype`` packed (:func:`.palette.colour_keys`).
    """

    def __init__(self, identity: bool, channels: int, dtype: np.dtype) -> None:
        self.identity = identity
        self.channels = channels
        self.dtype = np.dtype(dtype)
        self.keys = np.zeros(0, np.uint64)
        self.top = 0

    def indices(self, keys: np.ndarray) -> np.ndarray:
        """Palette index of each key (keys in run order), growing the palette as needed.

        Raises TerrathemeError (more than 256 colours in all).
        """
        if self.identity:
            self.top = max(self.top, int(keys.max()))
            return keys.astype(np.uint8)
        keys = keys.astype(np.uint64)
        known = np.isin(keys, self.keys)
        fresh, first = np.unique(keys[~known], return_index=True)
        self.keys = np.concatenate([self.keys, fresh[np.argsort(first, kind="stable")]])
        if self.keys.size > MAX_COLOURS:
            raise OptionError(
                f"image has more than the {MAX_COLOURS} colours a packed layer holds: "
                "reduce the palette ({reduce_palette})")
        # Sorted keys, then each key's place in the palette.
        order = np.argsort(self.keys)
        return order[np.searchsorted(self.keys[order], keys)].astype(np.uint8)

    @property
    def palette(self) -> np.ndarray:
        """``(K, C)`` palette of the keys seen so far."""
        if self.identity:
            return np.arange(self.top + 1, dtype=self.dtype)[:, None]
        return _palette.keys_to_colours(self.keys, self.channels, self.dtype)


def pack(
    image: np.ndarray,
    curve: str | CurveChoice | Curve = "hilbert",
    *,
    reduce_palette: bool = False,
    colours: np.ndarray | None = None,
    tile_bits: int | None = None,
    progress: ProgressFn | None = None,
) -> PackedLayer | TiledLayer:
    """Pack an index image into runs along a space-filling curve.

    Parameters
    ----------
    image : (H, W) or (H, W, C) uint8/uint16 ndarray
        Row 0 on top. Single-channel values are palette indices, else at most 256 colours.
    reduce_palette : bool
        Reduce more than 256 colours by k-means (``layer.report``) instead of refusing.
    tile_bits : int, optional
        A :class:`TiledLayer` of ``2^tile_bits`` tiles (6..16); forced past 65536 a side.

    Raises TerrathemeError for an empty image, unsupported pixels or too many colours.
    """
    choice = CurveChoice.parse(curve)
    arr, squeeze = check_image(image, max_side=MAX_TILED_SIDE)
    report: PaletteReport | None = None
    if reduce_palette:
        # Seed section 2.2: bring the image to a 256-colour palette first.
        arr, report = _palette.reduce_palette(arr)
    h, w = arr.shape[:2]
    if tile_bits is not None or needs_tiles(w, h):
        return _pack_tiles(arr, squeeze, choice, 16 if tile_bits is None else int(tile_bits),
                           colours, progress)
    best = None
    for i, c in enumerate(choice.curves):
        runs = image_runs(arr, c)
        if best is None or runs.steps.size < best[1].steps.size:
            best = (c, runs)
        if progress is not None:
            progress(i + 1, len(choice.curves))
    c, runs = best
    if colours is not None and not runs.identity:
        raise TerrathemeError("display colours need a single-channel index image (values < 256)")
    return PackedLayer.from_runs(w, h, c, runs.steps, runs.indices, runs.palette,
                                 identity=runs.identity, squeeze=squeeze, report=report,
                                 colours=colours)


def tile_from_runs(width: int, height: int, candidates: dict[Curve, tuple[np.ndarray,
                   np.ndarray]], palette: TilePalette) -> PackedLayer:
    """A tile of palette indices from its runs of keys along one or more curves.

    The curve with the fewest runs is kept; its keys become palette indices.
    """
    curve = min(candidates, key=lambda c: candidates[c][0].size)
    steps, keys = candidates[curve]
    values = palette.indices(keys)
    return PackedLayer.from_runs(width, height, curve, steps, values,
                                 np.arange(int(values.max()) + 1, dtype=np.uint8),
                                 identity=True, squeeze=True)


def _pack_tiles(arr: np.ndarray, squeeze: bool, choice: CurveChoice, tile_bits: int,
                colours: np.ndarray | None, progress: ProgressFn | None) -> TiledLayer:
    h, w, c = arr.shape
    side = 1 << tile_bits
    identity = c == 1 and int(arr.max()) < MAX_COLOURS
    if colours is not None and not identity:
        raise TerrathemeError("display colours need a single-channel index image (values < 256)")
    keys = arr[:, :, 0] if identity else colour_keys(arr)
    palette = TilePalette(identity, c, arr.dtype)
    rects = [(x, y, min(side, w - x), min(side, h - y))
             for y in range(0, h, side) for x in range(0, w, side)]
    blobs = []
    for i, (x, y, tw, th) in enumerate(rects):
        # Runs of the tile's keys along each curve asked for; the shorter is kept.
        cands = {cv: scan_runs(keys[y: y + th, x: x + tw], cv) for cv in choice.curves}
        blobs.append(tile_from_runs(tw, th, cands, palette).to_bytes())
        if progress is not None:
            progress(i + 1, len(rects))
    return TiledLayer.from_tile_bytes(w, h, tile_bits, blobs, palette.palette,
                                      identity=identity, squeeze=squeeze, colours=colours)


