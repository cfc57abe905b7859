"""Making any patch tileable, and measuring how visible a texture's wrap-around seam is.

``make_tileable`` runs two steps on the patch:

1. *Wrapping* (``TileableOptions.method``), one of

   * ``PERIODIC`` (default): the periodic component of the
     periodic-plus-smooth decomposition (L. Moisan, "Periodic plus smooth
     image decomposition", J. Math. Imaging Vision 39, 2011, eqs. (8)-(11)):
     the smooth image whose Laplacian is the wrap-edge jump is removed (one
     FFT solve per channel). Every texel keeps its detail and nothing is
     copied or averaged (no ghosts, no repeated strip). The wrap edge comes
     out a little *smoother* than the interior (``seam_score`` about 0.8:
     ``s`` also absorbs the natural texel-to-texel step there), which is
     invisible, unlike a step. Because of that, a patch that already tiles
     (``seam_score <= TileableOptions.tiles_already``) is not wrapped again:
     a periodic patch comes through this step unchanged.
   * ``CUT``: image quilting across the wrap edge (Efros & Freeman,
     SIGGRAPH 2001; :mod:`core.themes.seam_cut`): a half-shifted copy fills a narrow
     band around the edge, joined along minimum-error cuts with a few texels
     of feathering. No ghosts, but the band repeats part of the interior.
   * ``CROSSFADE``: the classic half-shift cross-fade, made *histogram
     preserving* (Heitz & Neyret, HPG 2018): both copies are Gaussianised
     per channel, blended with variance-preserving weights ``(w G_A + (1-w)
     G_B) / sqrt(w^2 + (1-w)^2)`` and mapped back through the patch's own
     histogram. Its wide blend doubles features (ghosts).

2. *Low-frequency flattening* (``TileableOptions.flatten``): the tile's
   large-scale brightness and colour trend -- its per-channel *periodic*
   Gaussian blur of sigma ``flatten * min(h, w)`` (at least
   ``FLATTEN_MIN_SIGMA`` texels) -- is subtracted (or divided out) and the
   mean restored. A shading gradient or a dark band is harmless in one patch
   but, once the patch is tiled, repeats as a regular grid that the eye picks
   out at once. Done after wrapping, the blur is exactly periodic, so the
   flattening cannot reopen the seam (measured: it leaves half the banding
   that flattening before wrapping, with mirrored borders, leaves).

Defaults were chosen with ``benchmarks/bench_tileable.py`` on Dubai photo
patches (32 to 256 texels), rated by :func:`seam_score` and
:mod:`core.themes.quality` (``repeat_score`` for ghosts and copied strips,
``lowfreq_score`` for banding).

Seam measure (``seam_score``): the mean absolute colour step across the
wrap edge (last column to first, last row to first) divided by the mean step
across the interior column (row) boundaries next to the edge; the larger of
the two axes. 1 means the wrap edge looks like any other line of the texture;
a photo crop that does not tile scores 2-10.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from scipy.ndimage import gaussian_filter
from scipy.special import ndtr
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.histogram import gaussianise
from terratheme.core.themes.library import validate_texture
from terratheme.core.themes.seam_cut import cut_wrap

#: the score below which a texture counts as seamless (the shipped themes' test)
SEAM_THRESHOLD = 1.5
#: smallest flattening blur (texels): on small patches a blur of 1/32 of the side eats the texture
FLATTEN_MIN_SIGMA = 4.0


class SeamMethod(StrEnum):
    """How the wrap edge is made seamless (see the module docstring)."""

    PERIODIC = "periodic"
    CUT = "cut"
    CROSSFADE = "crossfade"


class FlattenMode(StrEnum):
    """How the large-scale trend is removed: ``x - blur + mean`` or ``x / blur * mean``."""

    SUBTRACT = "subtract"
    DIVIDE = "divide"


@dataclass(frozen=True)
class TileableOptions:
    """Options of :func:`make_tileable`.

    Attributes
    ----------
    method : SeamMethod
        How the wrap edge is made seamless.
    flatten : float
        Sigma of the trend blur as a fraction of the patch's shorter side
        (at least ``FLATTEN_MIN_SIGMA`` texels); 0 keeps the patch's
        large-scale variation.
    flatten_mode : FlattenMode
        Subtract the trend (default) or divide it out.
    band : float
        CROSSFADE: width of the cross-fade ramp at each border, as a
        fraction of the patch size (0 < band <= 0.5).
    histogram : bool
        CROSSFADE: histogram-preserving blend (default) instead of a plain average.
    overlap : float
        CUT: how far from the wrap edge the cuts may run, as a fraction of
        the patch size (0 < overlap <= 0.25).
    feather : int
        CUT: texels over which each cut is softened (>= 0).
    tiles_already : float
        A patch whose own :func:`seam_score` is at most this already tiles
        and skips the wrap step (only flattening is applied); 0 always wraps.
    """

    method: SeamMethod = SeamMethod.PERIODIC
    flatten: float = 1.0 / 32.0
    flatten_mode: FlattenMode = FlattenMode.SUBTRACT
    band: float = 0.35
    histogram: bool = True
    overlap: float = 0.125
    feather: int = 2
    tiles_already: float = 1.2


def _check_options(options: TileableOptions) -> None:
    if not 0.0 < options.band <= 0.5:
        raise TerrathemeError(f"band must be in (0, 0.5], got {options.band}")
    if not 0.0 < options.overlap <= 0.25:
        raise TerrathemeError(f"overlap must be in (0, 0.25], got {options.overlap}")
    if not 0.0 <= options.flatten <= 1.0:
        raise TerrathemeError(f"flatten must be in [0, 1], got {options.flatten}")
    if options.tiles_already < 0:
        raise TerrathemeError(f"tiles_already must be >= 0, got {options.tiles_already}")
    if options.feather < 0:
        raise TerrathemeError(f"feather must be >= 0, got {options.feather}")
    for enum, value, field in (
        (SeamMethod, options.method, "method"),
        (FlattenMode, options.flatten_mode, "flatten_mode"),
    ):
        if value not in {e.value for e in enum}:
            choices = ", ".join(e.value for e in enum)
            raise TerrathemeError(f"{field} must be one of {choices}, got {value!r}")


def flatten_trend(img: np.ndarray, sigma: float, mode: FlattenMode) -> np.ndarray:
    """Remove a periodic image's large-scale per-channel trend, keeping its mean.

    Parameters
    ----------
    img : (h, w, c) float ndarray
        Treated as one period of a tiling (the blur wraps around).
    sigma : float
        Gaussian sigma of the trend, in texels.
    mode : FlattenMode

    Returns
    -------
    flat : (h, w, c) float32 ndarray
        ``img - trend + mean`` (SUBTRACT) or ``img * mean / trend`` (DIVIDE).
    """
    img = np.asarray(img, dtype=np.float32)
    # The trend: a heavy per-channel Gaussian blur, wrapping like the tiled texture
    # ("grid-wrap": scipy's "wrap" overlaps the first and last texel, a period of n - 1).
    trend = gaussian_filter(img, sigma=(sigma, sigma, 0), mode="grid-wrap")
    mean = img.mean(axis=(0, 1), keepdims=True)
    if FlattenMode(mode) is FlattenMode.DIVIDE:
        return img * (mean / np.maximum(trend, 1.0))
    return img - trend + mean


def periodic_component(img: np.ndarray) -> np.ndarray:
    """Periodic component of Moisan's periodic-plus-smooth decomposition.

    Parameters
    ----------
    img : (h, w, c) float ndarray

    Returns
    -------
    p : (h, w, c) float32 ndarray
        ``img - s``, where the smooth component ``s`` solves
        ``Laplacian(s) = v`` with periodic boundaries and zero mean, ``v`` being
        the boundary image of the wrap-edge jumps (Moisan 2011, eqs. (8)-(11)).
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


def _crossfade_wrap(cur: np.ndarray, options: TileableOptions) -> np.ndarray:
    """Two separable half-shift cross-fade passes (columns, then rows)."""
    h, w = cur.shape[:2]
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
    return cur


def make_tileable(patch: np.ndarray, options: TileableOptions = TileableOptions()) -> np.ndarray:
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
    _check_options(options)
    cur = img.astype(np.float32)
    # Step 1: make the wrap edges seamless (unless the patch already tiles).
    method = SeamMethod(options.method)
    tiles = options.tiles_already > 0 and seam_score(img) <= options.tiles_already
    if tiles:
        method = None
    if method is SeamMethod.PERIODIC:
        cur = periodic_component(cur)
    elif method is SeamMethod.CUT:
        # Columns first; the row pass keeps the column wrap (its cuts close up cyclically).
        cur = cut_wrap(cur, 1, options.overlap, options.feather)
        cur = cut_wrap(cur, 0, options.overlap, options.feather)
    elif method is SeamMethod.CROSSFADE:
        cur = _crossfade_wrap(cur, options)
    # Step 2: remove the large-scale brightness / colour trend (periodic blur).
    if options.flatten > 0:
        sigma = max(options.flatten * min(h, w), FLATTEN_MIN_SIGMA)
        cur = flatten_trend(cur, sigma, options.flatten_mode)
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
