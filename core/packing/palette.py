"""From an image to a palette and runs along a curve (seed sections 2.1-2.2).

A single-channel image of values 0..255 is an **index image** (``P`` = value, identity
palette, the seed's Fig. 2); any other image with at most 256 colours gets a palette in
order of first appearance along the curve. More colours are refused unless palette
reduction (k-means) is asked for, which reports its colour error (seed section 2.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from terratheme.core.curves.scan import scan_runs
from terratheme.core.curves.square import MAX_SIDE, Curve
from terratheme.core.errors import OptionError, TerrathemeError

MAX_COLOURS = 256
SUPPORTED_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16))


@dataclass(frozen=True)
class PaletteReport:
    """How much palette reduction changed an image.

    ``colours_before``, ``colours_after``: distinct colours; ``max_error``, ``mean_error``:
    Euclidean colour distance over texels, in the image's units (0..255 for 8-bit).
    """

    colours_before: int
    colours_after: int
    max_error: float
    mean_error: float


@dataclass(frozen=True)
class Runs:
    """An image as runs along a curve.

    Attributes
    ----------
    steps : (R,) uint32 ndarray
        0-based curve step of each run's last texel.
    indices : (R,) uint8 ndarray
        Palette index ``P`` of each run.
    palette : (K, C) ndarray of the image dtype
    identity : bool
        True when ``P`` is the pixel value of a single-channel index image.
    """

    steps: np.ndarray
    indices: np.ndarray
    palette: np.ndarray
    identity: bool


def check_image(image: np.ndarray, *, max_side: int = MAX_SIDE) -> tuple[np.ndarray, bool]:
    """Validate an input image; return it as ``(H, W, C)`` and whether it was 2-D.

    Raises TerrathemeError (empty image, more than 4 channels, a pixel type other than
    uint8/uint16, or a side over ``max_side`` (one layer's 65536 by default)).
    """
    arr = np.asarray(image)
    squeeze = arr.ndim == 2
    if squeeze:
        arr = arr[:, :, None]
    if arr.ndim != 3:
        raise TerrathemeError(f"image must be (H, W) or (H, W, C), got shape {arr.shape}")
    h, w, c = arr.shape
    if h == 0 or w == 0:
        raise TerrathemeError(f"image of {w} x {h} texels has no texels to pack")
    if not 1 <= c <= 4:
        raise TerrathemeError(f"image has {c} channels; 1 (index), 3 (RGB) or 4 (RGBA) expected")
    if arr.dtype not in SUPPORTED_DTYPES:
        raise TerrathemeError(
            f"pixel type {arr.dtype} cannot be packed: index layers are uint8 or uint16"
        )
    if w > max_side or h > max_side:
        raise TerrathemeError(
            f"image of {w} x {h} texels exceeds the {max_side} x {max_side} limit")
    return arr, squeeze


def colour_keys(arr: np.ndarray) -> np.ndarray:
    """One integer per texel holding all its channels: (H, W) uint32 or uint64."""
    bits = 8 * arr.dtype.itemsize
    kind = np.uint32 if bits * arr.shape[2] <= 32 else np.uint64
    keys = arr[:, :, 0].astype(kind)
    for ch in range(1, arr.shape[2]):
        keys |= arr[:, :, ch].astype(kind) << kind(bits * ch)
    return keys


def keys_to_colours(keys: np.ndarray, channels: int, dtype: np.dtype) -> np.ndarray:
    """Inverse of :func:`colour_keys` for a few keys: (K,) -> (K, C)."""
    bits = 8 * dtype.itemsize
    mask = (1 << bits) - 1
    keys = keys.astype(np.uint64)
    cols = [(keys >> np.uint64(bits * ch)) & np.uint64(mask) for ch in range(channels)]
    return np.stack(cols, axis=1).astype(dtype)


def image_runs(arr: np.ndarray, curve: Curve) -> Runs:
    """Palette and runs of a checked ``(H, W, C)`` image with at most 256 colours.

    Raises TerrathemeError (more than 256 distinct colours).
    """
    if arr.shape[2] == 1 and int(arr.max()) < MAX_COLOURS:
        # Index image: P is the pixel value (seed Fig. 2).
        steps, values = scan_runs(arr[:, :, 0].astype(np.uint8, copy=False), curve)
        palette = np.arange(int(values.max()) + 1, dtype=arr.dtype)[:, None]
        return Runs(steps, values, palette, identity=True)
    # Colour image: runs of packed colours, then the palette in order of first appearance.
    steps, values = scan_runs(colour_keys(arr), curve)
    uniq, first, inverse = np.unique(values, return_index=True, return_inverse=True)
    if uniq.size > MAX_COLOURS:
        raise OptionError(
            f"image has {uniq.size} colours, more than the {MAX_COLOURS} a packed layer holds: "
            "reduce the palette ({reduce_palette})"
        )
    order = np.argsort(first, kind="stable")
    rank = np.empty(uniq.size, dtype=np.uint8)
    rank[order] = np.arange(uniq.size, dtype=np.uint8)
    palette = keys_to_colours(uniq[order], arr.shape[2], arr.dtype)
    return Runs(steps, rank[inverse.reshape(-1)], palette, identity=False)


def reduce_palette(arr: np.ndarray, *, seed: int = 0) -> tuple[np.ndarray, PaletteReport]:
    """A ``(H, W, C)`` image reduced to at most 256 colours (k-means, OpenCV; unchanged if it
    has no more), same dtype, and its :class:`PaletteReport`."""
    import cv2

    keys = colour_keys(arr).reshape(-1)
    uniq, inverse = np.unique(keys, return_inverse=True)
    colours = keys_to_colours(uniq, arr.shape[2], arr.dtype).astype(np.float32)
    if uniq.size <= MAX_COLOURS:
        return arr, PaletteReport(int(uniq.size), int(uniq.size), 0.0, 0.0)
    # Cluster the distinct colours, weighted by repetition through a texel sample.
    rng = np.random.default_rng(seed)
    sample = inverse[rng.integers(0, inverse.size, size=min(inverse.size, 200_000))]
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 20, 0.5)
    cv2.setRNGSeed(seed)
    _, _, centres = cv2.kmeans(colours[sample], MAX_COLOURS, None, criteria, 2,
                               cv2.KMEANS_PP_CENTERS)
    top = float(np.iinfo(arr.dtype).max)
    centres = np.clip(np.rint(centres), 0, top)
    # Map every distinct colour to its nearest centre.
    from scipy.spatial import cKDTree

    _, nearest = cKDTree(centres).query(colours)
    mapped = centres[nearest]
    error = np.linalg.norm(mapped - colours, axis=1)
    per_texel = error[inverse]
    reduced = mapped[inverse].astype(arr.dtype).reshape(arr.shape)
    after = np.unique(mapped, axis=0).shape[0]
    return reduced, PaletteReport(int(uniq.size), int(after), float(per_texel.max()),
                                  float(per_texel.mean()))


def as_palette(palette: np.ndarray) -> np.ndarray:
    """A palette as a ``(K, C)`` uint8 or uint16 array (plain integers: the smallest that fits).

    Raises TerrathemeError (colours that are not integers of 0 to 65535, or not 1 to 256 of
    them).
    """
    palette = np.asarray(palette)
    if palette.ndim == 1:
        palette = palette[:, None]
    if palette.dtype not in (np.uint8, np.uint16):
        # Plain integer palettes (e.g. Python lists) take the smallest fitting type.
        if palette.dtype.kind not in "iu" or palette.min() < 0 or palette.max() > 65535:
            raise TerrathemeError(f"palette of {palette.dtype}: uint8 or uint16 colours expected")
        palette = palette.astype(np.uint8 if palette.max() < 256 else np.uint16)
    if not 1 <= palette.shape[0] <= 256 or palette.ndim != 2:
        raise TerrathemeError(f"palette of shape {palette.shape}: 1 to 256 colours expected")
    return palette


def check_colours(colours: np.ndarray | None, k: int, identity: bool) -> np.ndarray | None:
    """Display colours cut to the palette's ``k`` entries, read-only, or None."""
    if colours is None:
        return None
    colours = np.asarray(colours)
    if not identity:
        raise TerrathemeError("display colours belong to index layers (identity palette) only")
    if colours.ndim != 2 or colours.shape[1] not in (3, 4) or colours.shape[0] < k:
        raise TerrathemeError(
            f"display colours of shape {colours.shape}: ({k} or more, 3 or 4) expected")
    if colours.dtype.kind not in "iu" or colours.min() < 0 or colours.max() > 255:
        raise TerrathemeError("display colours must be 0..255 integers")
    out = np.ascontiguousarray(colours[:k], dtype=np.uint8)
    out.setflags(write=False)
    return out


def palette_values(palette: np.ndarray, identity: bool, squeeze: bool,
                   indices: np.ndarray) -> np.ndarray:
    """Texel values of (...) uint8 palette ``indices``: (...) or (..., C), as the packed image was.

    ``identity`` and ``squeeze`` are the layer's flags (index layer; 2-D image).
    """
    if identity:
        # Index layer: the palette index is the value; no colour gather needed.
        values = indices.astype(palette.dtype, copy=False)
        return values if squeeze else values[..., None]
    values = palette[indices]
    return values[..., 0] if squeeze else values


def scalar_values(palette: np.ndarray, squeeze: bool) -> list:
    """Per palette index, what a scalar lookup returns (``squeeze``: channel 0)."""
    return list(palette[:, 0]) if squeeze else list(palette)
