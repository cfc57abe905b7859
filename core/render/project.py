"""Rendering a project: full resolution, or a reduced overview that never renders it first."""

from __future__ import annotations

import math
import os
from collections.abc import Callable

import numpy as np
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.georef import scale_georeference
from terratheme.core.model.project import ThematicTexture, load_project
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.overview import render_overview
from terratheme.core.render.renderer import RenderOptions, render_cells

Progress = Callable[[int, int], None]


def project_style(project: ThematicTexture) -> RenderOptions:
    """The render options a project asks for (``metadata["render"]``), else the paper's rule.

    ``metadata["render"]`` is ``{"boundary": {BoundaryOptions fields}}`` (written
    by ``convert``); anything else there is refused with one line.
    """
    style = project.metadata.get("render")
    if style is None:
        return RenderOptions()
    if not isinstance(style, dict) or set(style) - {"boundary"}:
        raise TerrathemeError(f"project render style must be {{'boundary': {{...}}}}, got "
                              f"{str(style)[:60]}")
    boundary = style.get("boundary")
    if boundary is None:
        return RenderOptions()
    if not isinstance(boundary, dict):
        raise TerrathemeError("project render style: boundary must be an object")
    try:
        return RenderOptions(boundary=BoundaryOptions(**boundary))
    except TypeError as exc:
        raise TerrathemeError(f"project render style: bad boundary options ({exc})") from None


def render_project(
    project: ThematicTexture,
    region: tuple[int, int, int, int] | None = None,
    scale: float = 1.0,
    *,
    options: RenderOptions | None = None,
    progress: Progress | None = None,
) -> np.ndarray:
    """Render a project's texture, or a reduced-resolution overview when ``scale < 1``.

    ``region`` is in full-resolution texels; ``options`` default to the project's
    own style (:func:`project_style`).
    """
    if not (0.0 < float(scale) <= 1.0):
        raise TerrathemeError(f"scale must be in (0, 1], got {scale}")
    textures = project.library.textures
    if options is None:
        options = project_style(project)
    if float(scale) == 1.0:
        return render_cells(project.grid.indices, textures, project.grid.cell, region,
                            options=options, progress=progress, colour_map=project.colour_map)
    return render_overview(project.grid.indices, textures, project.grid.cell, region,
                           scale=float(scale), saddle=options.saddle,
                           colour_map=project.colour_map, boundary=options.boundary)


def photo_extent(project: ThematicTexture) -> tuple[int, int]:
    """``(w, h)``: the size of the photo the project was made from, else the texture's.

    A converted grid covers whole cells, so its texture can be a little larger than
    the photo; renders default to the photo's extent so they lie on its pixel grid.
    """
    tw, th = project.grid.texture_size
    size = project.metadata.get("photo_size")
    if size is None:
        return tw, th
    # Two JSON numbers (not bools), finite, whole and at least 1.
    if not (isinstance(size, list | tuple) and len(size) == 2 and all(
            type(v) in (int, float) and math.isfinite(v) and v == int(v) >= 1 for v in size)):
        raise TerrathemeError(f"metadata photo_size must be two positive whole numbers "
                              f"(width, height), got {size!r}"[:200])
    return min(int(size[0]), tw), min(int(size[1]), th)


def render_georeference(project: ThematicTexture, region: tuple[int, int, int, int],
                        out_size: tuple[int, int]) -> dict:
    """The georeference of a render of ``region`` at ``out_size = (w, h)`` (``{}`` if none).

    The project's georeference describes texel ``(0, 0)``; the render starts at
    the region's origin, one pixel covering ``region w / out w`` texels.
    """
    geo = project.metadata.get("georeference")
    if not geo:
        return {}
    x, y, w, h = region
    return scale_georeference(geo, w / out_size[0], h / out_size[1], offset=(x, y))


def load_checked_project(path: str | os.PathLike) -> ThematicTexture:
    """:func:`core.model.project.load_project`, then its render style and photo size checked.

    ``metadata["render"]`` is parsed here, not by core.model (which core.render
    builds on), so a bad style is one line naming the file before any work.
    """
    project = load_project(path)
    try:
        project_style(project)
        photo_extent(project)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{path}: {exc}") from None
    return project
