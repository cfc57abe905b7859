"""Making any patch tileable, and measuring how visible a texture's wrap-around seam is.

:func:`make_tileable` (1) wraps the edges with Moisan's periodic component, then (2)
removes the tile's large-scale trend with a periodic blur, which would repeat as a grid once
tiled. The wraps it was chosen against are peers in ``benchmarks/tileable_peers.py``.
:func:`seam_score`: about 1 when the wrap edge looks like any other line; a photo crop
that does not tile scores 2-10.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.library import validate_texture

#: the score below which a texture counts as seamless (the shipped themes' test)
SEAM_THRESHOLD = 1.5
#: smallest flattening blur (texels): on small patches a blur of 1/32 of the side eats the texture
FLATTEN_MIN_SIGMA = 4.0


@dataclass(frozen=True)
class TileableOptions:
    """Options of :func:`make_tileable`: ``flatten``, the trend blur sigma as a share of the
    shorter side (at least ``FLATTEN_MIN_SIGMA`` texels; 0 keeps the large-scale variation);
    ``tiles_already``, a patch whose :func:`seam_score` is at most this is not wrapped (0
    always wraps)."""

    flatten: float = 1.0 / 32.0
    tiles_already: float = 1.2


def _check_options(options: TileableOptions) -> None:
    if not 0.0 <= options.flatten <= 1.0:
        raise TerrathemeError(f"flatten must be in [0, 1], got {options.flatten}")
    if options.tiles_already < 0:
        raise TerrathemeError(f"tiles_already must be >= 0, got {options.tiles_already}")


def flatten_trend(img: np.ndarray, sigma: float) -> np.ndarray:
    """(h, w, c) float32 periodic ``img - trend + mean``, the trend a wrapping Gaussian of
    ``sigma`` texels."""
    img = np.asarray(img, dtype=np.float32)
    # The trend: a heavy per-channel Gaussian blur, wrapping like the tiled texture
    # ("grid-wrap": scipy's "wrap" overlaps the first and last texel, a period of n - 1).
    trend = gaussian_filter(img, sigma=(sigma, sigma, 0), mode="grid-wrap")
    return img - trend + img.mean(axis=(0, 1), keepdims=True)


def periodic_component(img: np.ndarray) -> np.ndarray:
    """(h, w, c) float32 periodic component of Moisan's periodic-plus-smooth decomposition.

    ``img - s``, where ``Laplacian(s) = v`` with periodic boundaries and zero mean, ``v``
    the wrap-edge jumps (Moisan 2011, eqs. (8)-(11)).
    """
    u = np.asarray(img, dtype=np.float64)
    h, w = u.shape[:2]
    # Boundary image v: the jump across each wrap edge, at both texels beside it (eq. 9).
    v = np.zeros_like(u)
    v[0] += u[-1] - u[0]
    v[-1] += u[0] - u[-1]
    v[:, 0] += u[:, -1] - u[:, 0]
    v[:, -1] += u[:, 0] - u[:, -1]
    # s_hat = v_hat / (2 cos(2 pi q / h) + 2 cos(2 pi r / w) - 4), s_hat[0, 0] = 0 (eq. 11).
    q = np.arange(h)[:, None]
    r = np.arange(w)[None, :]
    den = 2.0 * np.cos(2.0 * np.pi * q / h) + 2.0 * np.cos(2.0 * np.pi * r / w) - 4.0
    den[0, 0] = 1.0
    s_hat = np.fft.fft2(v, axes=(0, 1)) / den[..., None]
    s_hat[0, 0] = 0.0
    s = np.real(np.fft.ifft2(s_hat, axes=(0, 1)))
    return (u - s).astype(np.float32)


def make_tileable(patch: np.ndarray, options: TileableOptions = TileableOptions()) -> np.ndarray:
    """(h, w, 3) uint8 tile of an (h, w, 3) patch (at least 4 x 4), seamless both ways."""
    img = validate_texture(patch, name="patch")
    h, w = img.shape[:2]
    if h < 4 or w < 4:
        raise TerrathemeError(f"patch {w} x {h} is too small to make tileable (need 4 x 4)")
    _check_options(options)
    cur = img.astype(np.float32)
    # Step 1: make the wrap edges seamless (unless the patch already tiles).
    if not (options.tiles_already > 0 and seam_score(img) <= options.tiles_already):
        cur = periodic_component(cur)
    # Step 2: remove the large-scale brightness / colour trend (periodic blur).
    if options.flatten > 0:
        sigma = max(options.flatten * min(h, w), FLATTEN_MIN_SIGMA)
        cur = flatten_trend(cur, sigma)
    return np.clip(np.rint(cur), 0, 255).astype(np.uint8)


def seam_score(texture: np.ndarray) -> float:
    """How visible the wrap-around seam is against the texture's own interior.

    Per axis, ``mean|T[:, 0] - T[:, -1]|`` over the mean step across the interior
    boundaries next to the edge (0|1, 1|2, w-3|w-2, w-2|w-1), so fast change near the edges
    is no seam; the larger axis. About 1 when seamless; ``SEAM_THRESHOLD`` is the pass mark.
    """
    img = validate_texture(texture, name="texture").astype(np.float32)
    h, w = img.shape[:2]
    if h < 3 or w < 3:
        raise TerrathemeError(f"texture {w} x {h} is too small for a seam score (need 3 x 3)")
    scores = []
    for axis, n in ((1, w), (0, h)):
        # Mean absolute step across each interior boundary i|i+1.
        steps = np.abs(np.diff(img, axis=axis)).mean(axis=(1 - axis, 2))
        near = sorted({0, 1, n - 3, n - 2} & set(range(n - 1)))
        interior = float(steps[near].mean())
        wrap = float(np.abs(np.take(img, 0, axis=axis) - np.take(img, -1, axis=axis)).mean())
        # A flat texture has no interior variation: any wrap step is a seam.
        if interior > 1e-6:
            scores.append(wrap / interior)
        else:
            scores.append(0.0 if wrap < 1e-6 else float("inf"))
    return max(scores)
