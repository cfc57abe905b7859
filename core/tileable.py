"""Making any patch tileable, and measuring how visible a texture's wrap-around seam is.

Method (``make_tileable``): two separable passes of the classic
*half-shift cross-fade*. Pass 1 blends the patch ``A`` with its copy shifted
by half a width, ``B(x, y) = A(x + W/2, y)``, as ``w(x) A + (1 - w(x)) B``:
``w`` is 0 on the left/right borders (where ``B`` shows ``A``'s continuous
interior, so the wrap is seamless) and 1 in a central band (where ``B`` has
its own seam, at ``x = W/2``, and is not used). Pass 2 does the same
vertically on the result; both terms of pass 2 wrap horizontally, so
pass 1's tileability is kept. The cross-fade is *histogram preserving*
(Heitz & Neyret, HPG 2018): both copies are Gaussianised per channel,
blended with variance-preserving weights ``(w G_A + (1-w) G_B) /
sqrt(w^2 + (1-w)^2)`` and mapped back through the patch's own histogram, so
the blended band neither washes out nor ghosts as a plain average does.

Seam measure (``seam_score``): the mean absolute colour step across the
wrap edge (last column to first, last row to first) divided by the mean step
across the interior column (row) boundaries next to the edge; the larger of
the two axes. 1 means the wrap edge looks like any other line of the texture;
a photo crop that does not tile scores 2-10.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from core.errors import TerrathemeError
from core.render_pack import gaussianise
from core.themes import validate_texture

#: the score below which a texture counts as seamless (the shipped themes' test)
SEAM_THRESHOLD = 1.5


@dataclass(frozen=True)
class TileableOptions:
    """Options of :func:`make_tileable`.

    Attributes
    ----------
    band : float
        Width of the cross-fade ramp at each border, as a fraction of the
        patch size (0 < band <= 0.5); 0.5 fades over the whole patch.
    histogram : bool
        Histogram-preserving cross-fade (default) instead of a plain average.
    """

    band: float = 0.35
    histogram: bool = True


def _ramp(n: int, band: float) -> np.ndarray:
    """(n,) weight: 0 at the borders, smoothstep up to 1 over ``band * n`` texels."""
    pos = np.arange(n) + 0.5
    dist = np.minimum(pos, n - pos) / max(band * n, 1e-9)
    t = np.clip(dist, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _crossfade(a: np.ndarray, b: np.ndarray, w: np.ndarray, hist: tuple | None) -> np.ndarray:
    """Blend ``a`` and ``b`` (float, (h, w, 3)) with weight ``w`` on ``a`` (broadcastable)."""
    if hist is None:
        return w * a + (1.0 - w) * b
    ga, gb, sorted_vals = hist
    # Variance-preserving blend of Gaussianised values (Heitz & Neyret 2018).
    g = (w * ga + (1.0 - w) * gb) / np.sqrt(w * w + (1.0 - w) ** 2)
    # Back through the patch's own histogram (their inverse transform): Phi(g) -> rank -> value.
    n = sorted_vals.shape[1]
    pos = np.clip(ndtr(g) * n - 0.5, 0, n - 1)
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, n - 1)
    f = pos - lo
    out = np.empty_like(g)
    for c in range(3):
        sv = sorted_vals[c]
        out[..., c] = sv[lo[..., c]] * (1 - f[..., c]) + sv[hi[..., c]] * f[..., c]
    return out


def make_tileable(patch: np.ndarray, options: TileableOptions = TileableOptions()) -> np.ndarray:  # noqa: B008
    """Make a patch tile seamlessly in both directions.

    Parameters
    ----------
    patch : (h, w, 3) uint8 ndarray
        Any texture patch, at least 4 x 4.
    options : TileableOptions

    Returns
    -------
    tile : (h, w, 3) uint8 ndarray
        Left edge continues the right edge, top continues bottom.
    """
    img = validate_texture(patch, name="patch")
    h, w = img.shape[:2]
    if h < 4 or w < 4:
        raise TerrathemeError(f"patch {w} x {h} is too small to make tileable (need 4 x 4)")
    if not 0.0 < options.band <= 0.5:
        raise TerrathemeError(f"band must be in (0, 0.5], got {options.band}")
    cur = img.astype(np.float32)
    for axis, n in ((1, w), (0, h)):
        # Half-shifted copy: its interior now lies on the wrap edge.
        shifted = np.roll(cur, -(n // 2), axis=axis)
        ramp = _ramp(n, options.band).astype(np.float32)
        wgt = ramp[None, :, None] if axis == 1 else ramp[:, None, None]
        hist = None
        if options.histogram:
            ref = np.clip(np.rint(cur), 0, 255).astype(np.uint8)
            ga, sorted_vals = gaussianise(ref)
            hist = (ga, np.roll(ga, -(n // 2), axis=axis), sorted_vals)
        cur = _crossfade(cur, shifted, wgt, hist)
    return np.clip(np.rint(cur), 0, 255).astype(np.uint8)


def seam_score(texture: np.ndarray) -> float:
    """How visible the wrap-around seam is against the texture's own interior.

    Parameters
    ----------
    texture : (h, w, 3) uint8 ndarray (at least 3 x 3)

    Returns
    -------
    score : float
        For columns: ``mean|T[:, 0] - T[:, -1]|`` (the step across the wrap
        edge) divided by the mean step across the interior boundaries next
        to it (columns 0|1, 1|2 and w-3|w-2, w-2|w-1), so a texture whose
        colour changes fast near its edges is not mistaken for a seam; the
        same for rows; the larger of the two. About 1 for a seamless
        texture; ``SEAM_THRESHOLD`` is the pass mark.
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
