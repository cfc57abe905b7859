"""Rendering a project: full resolution, or a reduced overview that never renders it first."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from core.errors import TerrathemeError
from core.model.project import ThematicTexture
from core.render.overview import render_overview
from core.render.renderer import RenderOptions, render_cells

Progress = Callable[[int, int], None]


def render_project(
    project: ThematicTexture,
    region: tuple[int, int, int, int] | None = None,
    scale: float = 1.0,
    *,
    options: RenderOptions = RenderOptions(),  # noqa: B008 (frozen)
    progress: Progress | None = None,
) -> np.ndarray:
    """Render a project's texture, or a reduced-resolution overview when ``scale < 1``.

    Parameters
    ----------
    project : ThematicTexture
    region : (x, y, w, h), optional
        In full-resolution texels.
    scale : float in (0, 1]
        Output texels per full-resolution texel; below 1 the overview
        renderer is used (it never renders full resolution first).
    options : RenderOptions
    progress : callable(done, total), optional

    Returns
    -------
    image : (round(h*scale), round(w*scale), 3) uint8 ndarray
    """
    if not (0.0 < float(scale) <= 1.0):
        raise TerrathemeError(f"scale must be in (0, 1], got {scale}")
    textures = project.library.textures
    if float(scale) == 1.0:
        return render_cells(project.grid.indices, textures, project.grid.cell, region,
                            options=options, progress=progress)
    return render_overview(project.grid.indices, textures, project.grid.cell, region,
                           scale=float(scale), saddle=options.saddle)
