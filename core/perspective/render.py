"""Rendering a textured ground plane: the public entry points.

``PreparedTexture`` prefilters a texture once (mip pyramid, the seed's
family of copies, optionally kept in a :class:`~core.io.disk_cache.DiskCache`) and
renders any number of frames as the camera moves; ``render_perspective`` is
the one-call form.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.disk_cache import Arrays, DiskCache
from terratheme.core.perspective.baselines import TRILINEAR, mip_kernel, texel_kernel
from terratheme.core.perspective.ewa import EWA_LUT, ewa_kernel
from terratheme.core.perspective.family import (
    ParallelogramFamily,
    build_family,
    family_layout,
)
from terratheme.core.perspective.lookup import coverage_kernel
from terratheme.core.perspective.mapping import Camera, PlaneMapping, check_size, view_mapping
from terratheme.core.perspective.options import PYRAMID_METHODS, FilterOptions, Method
from terratheme.core.perspective.reference import reference_kernel
from terratheme.core.perspective.texture import (
    MipPyramid,
    build_pyramid,
    power_of_two_grid,
    power_of_two_side,
    stored_texture,
)

Progress = Callable[[int, int], None]

#: rows rendered between two progress reports
BAND_ROWS = 64
#: bump when the family's construction changes (old cache entries then miss)
FAMILY_VERSION = 3


def family_key(texels: np.ndarray, max_lambda_log2: int, skew_oversampling: int) -> str:
    """Hex SHA-256 of a texture's family: its texels ``(h, w, C)``, shape, type and options."""
    digest = hashlib.sha256()
    digest.update(json.dumps([FAMILY_VERSION, list(texels.shape), str(texels.dtype),
                              int(max_lambda_log2), int(skew_oversampling)]).encode())
    digest.update(np.ascontiguousarray(texels).data)
    return digest.hexdigest()


@dataclass(frozen=True)
class RenderResult:
    """A rendered frame: ``image`` (h, w, C) float32 (in [0, 1] for integer textures),
    ``texel_reads`` (h, w) int32 per pixel (0 for sky) and the eq. 1 ``mapping`` used."""

    image: np.ndarray
    texel_reads: np.ndarray
    mapping: PlaneMapping

    @property
    def mean_reads(self) -> float:
        """Texels read per ground (non-sky) pixel."""
        ground = self.texel_reads > 0
        return float(self.texel_reads[ground].mean()) if ground.any() else 0.0


def sky_vector(sky: tuple[float, ...], channels: int) -> np.ndarray:
    """The sky colour as ``(channels,) float64`` (grey for 1 channel, opaque for 4)."""
    s = [float(c) for c in sky]
    if len(s) == channels:
        return np.array(s)
    if len(s) == 1:
        return np.full(channels, s[0])
    if channels == 1:
        return np.array([float(np.mean(s[:3]))])
    if channels == 4 and len(s) == 3:
        return np.array([*s, 1.0])
    if channels == 2 and len(s) >= 3:
        return np.array([float(np.mean(s[:3])), 1.0])
    raise TerrathemeError(f"sky colour has {len(s)} values for a {channels}-channel texture")


class PreparedTexture:
    """A texture prefiltered for perspective rendering.

    ``texture`` (h, w) or (h, w, C), C in 1..4: uint8 / uint16 keep their type (the
    prefiltered data too), others become float32 in [0, 1]; any size (resampled to
    powers of two, :func:`~.texture.power_of_two_grid`). The structures of
    ``options``' filter are built now, others on first use; families are loaded
    from and stored into ``cache``.
    """

    def __init__(self, texture: np.ndarray, options: FilterOptions | None = None,
                 progress: Progress | None = None, cache: DiskCache | None = None) -> None:
        self.options = options if options is not None else FilterOptions()
        self.stored = stored_texture(texture)
        w, h = self.stored.size
        self.grid_size = (power_of_two_side(w), power_of_two_side(h))
        self.su, self.sv = self.grid_size[0] / w, self.grid_size[1] / h
        self.cache = cache
        self.cache_hit: bool | None = None
        self._pyramid: MipPyramid | None = None
        self._families: dict[tuple[int, int], ParallelogramFamily] = {}
        self._ensure(self.options, progress)

    @property
    def channels(self) -> int:
        return self.stored.channels

    @property
    def texture_size(self) -> tuple[int, int]:
        """``(width, height)`` of the input in texels."""
        return self.stored.size

    def _grid(self) -> np.ndarray:
        """The texture resampled to the power-of-two grid, float32 stored units."""
        return power_of_two_grid(self.stored)[0]

    @property
    def pyramid(self) -> MipPyramid:
        if self._pyramid is None:
            self._pyramid = build_pyramid(self._grid(), self.stored.texels.dtype)
        return self._pyramid

    def family(self, options: FilterOptions | None = None,
               progress: Progress | None = None) -> ParallelogramFamily:
        """The prefiltered copies for ``options`` (built once, or loaded from the cache)."""
        opt = options if options is not None else self.options
        key = (opt.max_lambda_log2, opt.skew_oversampling)
        if key not in self._families:
            fam = None
            if self.cache is not None:
                cache_key = family_key(self.stored.texels, *key)
                fam = self.cache.load(cache_key, "family", lambda a: self._cached_family(a, key))
                self.cache_hit = fam is not None
            if fam is None:
                fam = build_family(self._grid(), *key, dtype=self.stored.texels.dtype,
                                   progress=progress)
                if self.cache is not None:
                    self.cache.store(cache_key, "family", {"cells": fam.buf})
            self._families[key] = fam
        return self._families[key]

    def _cached_family(self, arrays: Arrays, key: tuple[int, int]) -> ParallelogramFamily | None:
        """The family of a cache entry's cells, if they are exactly what this texture's family
        holds: the layout comes from the texture, never from the entry."""
        start, count, total = family_layout(self.grid_size, *key)
        cells = arrays.get("cells")
        if (set(arrays) != {"cells"} or cells.dtype != self.stored.texels.dtype
                or cells.shape != (total, self.channels)
                or (cells.dtype.kind == "f" and not np.isfinite(cells).all())):
            return None
        return ParallelogramFamily(cells, start, count, self.grid_size, *key)

    def memory_bytes(self, options: FilterOptions | None = None) -> int:
        """Bytes of texture data the method of ``options`` reads from (the input included)."""
        opt = options if options is not None else self.options
        base = int(self.stored.texels.nbytes)
        if opt.method == Method.PARALLELOGRAM:
            return self.family(opt).nbytes + base
        if opt.method in PYRAMID_METHODS:
            return self.pyramid.nbytes
        return base

    def _ensure(self, opt: FilterOptions, progress: Progress | None = None) -> None:
        if opt.method == Method.PARALLELOGRAM:
            self.family(opt, progress)
        elif opt.method in PYRAMID_METHODS:
            _ = self.pyramid

    def render(self, view: PlaneMapping | Camera, size: tuple[int, int],
               options: FilterOptions | None = None,
               progress: Progress | None = None) -> RenderResult:
        """Render a ``size = (w, h)`` frame of the plane for ``view`` (PlaneMapping or Camera).

        ``options`` overrides the object's for this frame; ``progress(done_rows, total_rows)``.
        Returns a :class:`RenderResult`; pixels with ``z <= 0`` are sky.
        """
        opt = options if options is not None else self.options
        w, h = check_size(size)
        mapping = view_mapping(view, (w, h), self.texture_size)
        self._ensure(opt)
        sky = sky_vector(opt.sky, self.channels)
        image = np.empty((h, w, self.channels), np.float32)
        reads = np.zeros((h, w), np.int32)
        for y0 in range(0, h, BAND_ROWS):
            y1 = min(h, y0 + BAND_ROWS)
            img_band, rd_band = self._render_band(mapping, opt, w, y0, y1, sky)
            image[y0:y1] = img_band
            reads[y0:y1] = rd_band
            if progress is not None:
                progress(y1, h)
        return RenderResult(image, reads, mapping)

    def _render_band(self, mapping: PlaneMapping, opt: FilterOptions, w: int, y0: int, y1: int,
                     sky: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        bh = y1 - y0
        c = self.channels
        out = np.zeros((bh * w, c), np.float32)
        m = opt.method
        top = self.stored.top
        tex = self.stored.texels.reshape(-1, c)
        tw, th = self.stored.size
        if m in (Method.NEAREST, Method.BILINEAR, Method.REFERENCE):
            # these read the input texture itself
            u, v, z, dux, dvx, duy, dvy = _grid(mapping, w, y0, y1)
            valid = (z > 0) & np.isfinite(u) & np.isfinite(v)
            if m in (Method.NEAREST, Method.BILINEAR):
                reads = texel_kernel(tex, th, tw, u, v, m == Method.BILINEAR, valid, out)
            else:
                reads = reference_kernel(
                    tex, th, tw, mapping.coefficients(), w, bh, y0, dux, dvx, duy, dvy,
                    float(opt.reference_density), int(opt.reference_min_samples),
                    int(opt.reference_max_samples), sky * top, out)
                # the reference blends the sky per sub-sample
                out /= np.float32(top)
                return out.reshape(bh, w, c), reads.reshape(bh, w)
        else:
            # the others read the power-of-two grid
            u, v, z, dux, dvx, duy, dvy = _grid(mapping.scaled(self.su, self.sv), w, y0, y1)
            valid = (z > 0) & np.isfinite(u) & np.isfinite(v)
            if m != Method.EWA and opt.aperture != 1.0:
                dux, dvx, duy, dvy = (d * opt.aperture for d in (dux, dvx, duy, dvy))
            gw, gh = self.grid_size
            if m == Method.PARALLELOGRAM:
                fam = self.family(opt)
                k, so = fam.max_lambda_log2, fam.skew_oversampling
                reads = coverage_kernel(
                    fam.buf, fam.start, fam.count, gw, gh, k, so,
                    float(opt.cells_per_footprint), tex, tw, th, self.su, self.sv,
                    u, v, dux, dvx, duy, dvy, valid, out)
            else:
                pyr = self.pyramid
                args = (pyr.buf, pyr.offsets, pyr.heights, pyr.widths, u, v, dux, dvx, duy, dvy)
                if m in (Method.TRILINEAR, Method.ANISO):
                    probes = TRILINEAR if m == Method.TRILINEAR else int(opt.max_anisotropy)
                    reads = mip_kernel(*args, probes, valid, out)
                else:
                    reads = ewa_kernel(*args, float(opt.max_anisotropy), EWA_LUT, valid, out)
        if top != 1.0:
            # integer storage back to [0, 1]
            out /= np.float32(top)
        out[~valid] = sky.astype(np.float32)
        return out.reshape(bh, w, c), reads.reshape(bh, w)


def _grid(mapping: PlaneMapping, w: int, y0: int, y1: int) -> tuple[np.ndarray, ...]:
    """Eqs. 1-2 at the pixel centres of rows ``[y0, y1)``, flattened (float64)."""
    x = np.arange(w, dtype=np.float64) + 0.5
    y = np.arange(y0, y1, dtype=np.float64) + 0.5
    xx, yy = np.meshgrid(x, y)
    u, v, z = mapping.evaluate(xx.ravel(), yy.ravel())
    d = mapping.derivatives(u, v, z)
    return (u, v, z, *d)


def render_perspective(texture: np.ndarray | PreparedTexture, view: PlaneMapping | Camera,
                       size: tuple[int, int] = (640, 360),
                       options: FilterOptions | None = None,
                       progress: Progress | None = None) -> np.ndarray:
    """One frame in one call: :meth:`PreparedTexture.render`'s (h, w, C) float32 image."""
    opt = options if options is not None else FilterOptions()
    prepared = texture if isinstance(texture, PreparedTexture) else PreparedTexture(texture, opt)
    return prepared.render(view, size, opt, progress).image


__all__ = ["PreparedTexture", "RenderResult", "render_perspective", "sky_vector"]
