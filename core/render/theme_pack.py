"""Theme data laid out for the render kernels, cached by texture content.

``pack_themes`` pre-tiles every theme to ``w + N`` columns (a cell row is one
contiguous slice) in one flat buffer; ``gaussian=True`` adds the histogram-preserving
blend's Gaussianised copies and inverse tables. Cached on the textures' bytes, so the
editor's many small viewport renders do not repeat the work.
"""

from __future__ import annotations

import hashlib
import threading
import weakref
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr
from terratheme.core.themes.histogram import gaussianise

_CACHE_SIZE = 16
#: entries and half-range of the inverse-transform tables of the histogram blend
LUT_SIZE = 4096
LUT_RANGE = 6.0
_cache: OrderedDict[tuple, object] = OrderedDict()
_lock = threading.Lock()
_identity: dict[tuple[int, ...], tuple[list, bytes]] = {}


@dataclass(frozen=True)
class PackedThemes:
    """Flat theme buffer for the kernels.

    ``flat`` (total,) uint8: theme ``k`` at ``off[k]``, ``th[k]`` rows of
    ``stride[k]`` elements. ``gflat``: Gaussianised values in the same layout and
    ``inv_lut`` (3K, LUT_SIZE) float32: row ``3k+c`` the inverse transform of theme
    ``k`` channel ``c`` over ``[-LUT_RANGE, LUT_RANGE]`` (histogram blend only).
    """

    flat: np.ndarray
    off: np.ndarray
    stride: np.ndarray
    th: np.ndarray
    tw: np.ndarray
    gflat: np.ndarray | None = None
    inv_lut: np.ndarray | None = None


def _frozen(t: np.ndarray) -> bool:
    """True for an array whose bytes cannot change (read-only and owning its data)."""
    return not t.flags.writeable and t.flags.owndata


def _key(textures: Sequence[np.ndarray], extra: tuple) -> tuple:
    # Frozen textures (every Theme's) are keyed by identity: no hashing per render.
    ids = tuple(id(t) for t in textures)
    with _lock:
        hit = _identity.get(ids)
    if hit is not None and all(r() is t for r, t in zip(hit[0], textures, strict=True)):
        return (hit[1], *extra)
    h = hashlib.blake2b(digest_size=16)
    for t in textures:
        h.update(np.asarray(t.shape, dtype=np.int64).tobytes())
        h.update(t.tobytes())
    digest = h.digest()
    if all(_frozen(t) for t in textures):
        with _lock:
            _identity[ids] = ([weakref.ref(t) for t in textures], digest)
            while len(_identity) > _CACHE_SIZE:
                _identity.pop(next(iter(_identity)))
    return (digest, *extra)


def _cached(key: tuple, make):
    with _lock:
        if key in _cache:
            _cache.move_to_end(key)
            return _cache[key]
    value = make()
    with _lock:
        _cache[key] = value
        while len(_cache) > _CACHE_SIZE:
            _cache.popitem(last=False)
    return value


def _tile_rows(tex: np.ndarray, extra: int) -> np.ndarray:
    """``tex`` continued to the right by ``extra`` columns (wrapping)."""
    h, w = tex.shape[:2]
    reps = -(-(w + extra) // w)
    return np.tile(tex, (1, reps, 1))[:, : w + extra]


def pack_themes(textures: Sequence[np.ndarray], n: int, *, gaussian: bool = False) -> PackedThemes:
    """Pack validated ``(h, w, 3) uint8`` textures for a cell width ``n``."""
    return _cached(_key(textures, (n, gaussian)), lambda: _pack(textures, n, gaussian))


def _pack(textures: Sequence[np.ndarray], n: int, gaussian: bool) -> PackedThemes:
    parts, gparts, luts = [], [], []
    off, stride, th, tw = [], [], [], []
    pos = 0
    # Fractional rank of every tabulated Gaussian value (Phi(g) * n - 0.5).
    g_axis = np.linspace(-LUT_RANGE, LUT_RANGE, LUT_SIZE)
    for tex in textures:
        h, w = tex.shape[:2]
        # Pre-tile horizontally so every cell row is a contiguous slice.
        ext = _tile_rows(tex, n)
        parts.append(ext.reshape(-1))
        off.append(pos)
        stride.append(ext.shape[1] * 3)
        th.append(h)
        tw.append(w)
        pos += ext.size
        if gaussian:
            g, sv = gaussianise(tex)
            gparts.append(_tile_rows(g, n).reshape(-1))
            rank = ndtr(g_axis) * sv.shape[1] - 0.5
            for c in range(3):
                luts.append(np.interp(rank, np.arange(sv.shape[1]), sv[c]).astype(np.float32))
    i64 = np.int64
    return PackedThemes(
        flat=np.concatenate(parts),
        off=np.array(off, i64),
        stride=np.array(stride, i64),
        th=np.array(th, i64),
        tw=np.array(tw, i64),
        gflat=np.concatenate(gparts) if gaussian else None,
        inv_lut=np.stack(luts) if gaussian else None,
    )
