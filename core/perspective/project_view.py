"""A texture at the level of detail a frame needs.

Where the finest pixel footprint covers ``2^l`` texels, the texture ``2^l`` times
smaller gives the same frame: :func:`project_texture` renders a project at that scale
with the overview renderer, never at full resolution first, so previews work for
projects larger than memory.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.project import ThematicTexture
from terratheme.core.perspective.mapping import Camera, PlaneMapping, camera_mapping, scaled_view
from terratheme.core.render.project import render_project

Progress = Callable[[int, int], None]

#: share of ground pixels allowed a footprint finer than the texture's texels
FINE_SHARE = 0.01


def finest_footprint(mapping: PlaneMapping, size: tuple[int, int]) -> float:
    """Texels per pixel of a frame's finest footprints: the ``FINE_SHARE`` quantile over ground
    pixels of the shorter pixel side (eq. 2), ``inf`` when no pixel sees the ground.
    """
    u, v, z, dux, dvx, duy, dvy = mapping.pixel_grid(size)
    ground = z > 0
    if not ground.any():
        return float("inf")
    shorter = np.minimum(np.hypot(dux, dvx), np.hypot(duy, dvy))[ground]
    return float(np.quantile(shorter, FINE_SHARE))


def texture_scale(mapping: PlaneMapping, size: tuple[int, int], texture_size: tuple[int, int],
                  max_side: int) -> float:
    """The scale (power of two, at most 1) at which to prepare a texture for a frame.

    The coarsest ``2^-l`` whose texels are no larger than the frame's finest
    footprints (:func:`finest_footprint`), and small enough that the longer
    side is at most ``max_side`` texels.
    """
    if max_side < 1:
        raise TerrathemeError(f"the largest texture side must be at least 1, got {max_side}")
    fine = finest_footprint(mapping, size)
    level = 0 if not np.isfinite(fine) or fine < 2.0 else int(np.floor(np.log2(fine)))
    longest = max(texture_size)
    while longest * 0.5 ** level > max_side:
        level += 1
    return 0.5 ** level if longest * 0.5 ** level >= 1 else 1.0 / longest


def project_texture(project: ThematicTexture, view: PlaneMapping | Camera, size: tuple[int, int],
                    max_side: int = 4096,
                    progress: Progress | None = None) -> tuple[np.ndarray, PlaneMapping | Camera]:
    """A project's texture at the scale a ``size`` (w, h) frame needs (at most ``max_side``
    a side), as (h', w', 3) uint8, and ``view`` (PlaneMapping or Camera, in full-resolution
    texels) in its texels. ``progress`` goes to the full-resolution renderer.
    """
    w, h = project.grid.texture_size
    full = view if isinstance(view, PlaneMapping) else camera_mapping(view, size, (w, h))
    scale = texture_scale(full, size, (w, h), max_side)
    texture = render_project(project, None, scale, progress=progress if scale == 1.0 else None)
    return texture, scaled_view(view, texture.shape[1] / w, texture.shape[0] / h)
