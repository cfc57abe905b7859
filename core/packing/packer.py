"""``pack(image) -> PackedLayer``: the packing algorithm of seed section 2.2."""

from __future__ import annotations

import enum
from collections.abc import Callable

import numpy as np

from core.curves.square import Curve
from core.errors import TerrathemeError
from core.packing import palette as _palette
from core.packing.layer import PackedLayer
from core.packing.palette import PaletteReport, check_image, image_runs


class CurveChoice(enum.Enum):
    """Which curve to scan with; ``AUTO`` keeps whichever gives fewer runs."""

    HILBERT = "hilbert"
    MORTON = "morton"
    AUTO = "auto"


def pack(
    image: np.ndarray,
    curve: str | CurveChoice | Curve = "hilbert",
    *,
    reduce_palette: bool = False,
    colours: np.ndarray | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> PackedLayer:
    """Pack an index image into runs along a space-filling curve.

    Parameters
    ----------
    image : (H, W) or (H, W, C) uint8/uint16 ndarray
        Row 0 is the top row. Single-channel values 0..255 are palette indices
        (``P`` = value); otherwise at most 256 distinct colours.
    curve : "hilbert" | "morton" | "auto"
    reduce_palette : bool
        Reduce images with more than 256 colours (k-means) instead of refusing;
        ``layer.report`` then says how much the colours changed.
    colours : (K, 3) or (K, 4) uint8 ndarray, optional
        Display colours of an index image's values (e.g. a palette PNG's table).
    progress : callable(done, total), optional

    Returns
    -------
    PackedLayer

    Raises
    ------
    TerrathemeError
        Empty image, unsupported pixel type, over 65536 texels a side, or more
        than 256 colours without ``reduce_palette``.
    """
    choice = _choice(curve)
    arr, squeeze = check_image(image)
    report: PaletteReport | None = None
    if reduce_palette:
        # Seed section 2.2: bring the image to a 256-colour palette first.
        arr, report = _palette.reduce_palette(arr)
    curves = [Curve.HILBERT, Curve.MORTON] if choice is CurveChoice.AUTO else [
        Curve[choice.name]]
    best = None
    for i, c in enumerate(curves):
        runs = image_runs(arr, c)
        if best is None or runs.steps.size < best[1].steps.size:
            best = (c, runs)
        if progress is not None:
            progress(i + 1, len(curves))
    c, runs = best
    h, w = arr.shape[:2]
    if colours is not None and not runs.identity:
        raise TerrathemeError("display colours need a single-channel index image (values < 256)")
    return PackedLayer.from_runs(w, h, c, runs.steps, runs.indices, runs.palette,
                                 identity=runs.identity, squeeze=squeeze, report=report,
                                 colours=colours)


def _choice(curve: str | CurveChoice | Curve) -> CurveChoice:
    if isinstance(curve, CurveChoice):
        return curve
    if isinstance(curve, Curve):
        return CurveChoice(curve.name.lower())
    try:
        return CurveChoice(str(curve).strip().lower())
    except ValueError:
        raise TerrathemeError(
            f"unknown curve {curve!r}: use 'hilbert', 'morton' or 'auto'"
        ) from None
