"""A texture at the level of detail a frame needs.

A low-angle frame seldom needs the texture's full resolution everywhere:
where even the finest pixel footprint covers ``2^l`` texels, the texture
``2^l`` times smaller gives the same frame. :func:`texture_scale` picks that
scale from the frame (bounded by a largest side), and :func:`project_texture`
renders a project's thematic texture at it with the overview renderer
(:func:`core.render.project.render_project`), which never renders the full
resolution first, so previews work for projects larger than memory.
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
    """Texels per pixel of the finest footprints of a frame.

    Parameters
    ----------
    mapping : PlaneMapping
        In texels of the full-resolution texture.
    size : (w, h)

    Returns
    -------
    float
        The ``FINE_SHARE`` quantile over ground pixels of the shorter of the
        pixel's two sides (eq. 2), ``inf`` when no pixel sees the ground.
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
    """A project's texture at the scale the frame needs, and the view in its texels.

    Parameters
    ----------
    project : ThematicTexture
    view : PlaneMapping or Camera
        In texels of the project's full-resolution texture.
    size : (w, h)
    max_side : int
        Largest side of the rendered texture.
    progress : callable(done, total) or None
        Passed to the full-resolution renderer (scale 1).

    Returns
    -------
    texture : (h', w', 3) uint8 ndarray
    view : the same view in texels of ``texture``
    """
    w, h = project.grid.texture_size
    full = view if isinstance(view, PlaneMapping) else camera_mapping(view, size, (w, h))
    scale = texture_scale(full, size, (w, h), max_side)
    texture = render_project(project, None, scale, progress=progress if scale == 1.0 else None)
    return texture, scaled_view(view, texture.shape[1] / w, texture.shape[0] / h)
