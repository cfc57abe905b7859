"""Making any patch tileable, and measuring how visible a texture's wrap-around seam is.

:func:`make_tileable` (1) wraps the edges (``SeamMethod``: Moisan's periodic component,
default; Efros & Freeman minimum-error cuts; or Heitz & Neyret's histogram-preserving
half-shift cross-fade ``(w G_A + (1-w) G_B) / sqrt(w^2 + (1-w)^2)``), then (2) removes the
tile's large-scale trend with a periodic blur, which would repeat as a grid once tiled.
:func:`seam_score`: about 1 when the wrap edge looks like any other line; a photo crop
that does not tile scores 2-10.
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
    flatten : float
        Trend blur sigma as a share of the shorter side (at least ``FLATTEN_MIN_SIGMA``
        texels); 0 keeps the large-scale variation.
    flatten_mode : FlattenMode
    band : float
        CROSSFADE: ramp width at each border, share of the side (0 < band <= 0.5).
    histogram : bool
        CROSSFADE: histogram-preserving blend instead of a plain average.
    overlap : float
        CUT: how far from the wrap edge the cuts may run, share of the side (<= 0.25).
    feather : int
        CUT: texels over which each cut is softened.
    tiles_already : float
        A patch whose :func:`seam_score` is at most this is not wrapped; 0 always wraps.
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
    """(h, w, c) float32 periodic ``img`` without its large-scale per-channel trend.

    ``img - trend + mean`` (SUBTRACT) or ``img * mean / trend`` (DIVIDE); the trend is a
    wrapping Gaussian of ``sigma`` texels.
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
    """(h, w, 3) uint8 tile of an (h, w, 3) patch (at least 4 x 4), seamless both ways."""
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
