"""A render larger than memory: a tiled GeoTIFF with overviews, written band by band.

A whole region may not fit in memory (400 x 400 km at 1 m is 480 GB of RGB), so
:func:`write_texture_tiff` renders ``TILE``-row bands (the same texels as a whole
render) and hands them to :func:`core.exchange.cog.write_cog` (a Cloud Optimized
GeoTIFF, overviews by 2 x 2 means). Memory is one band; the disk needs about twice
the output. Levels over :data:`MAX_LEVEL_BYTES` (classic TIFF) are refused up front.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np
from terratheme.core.errors import OptionError
from terratheme.core.exchange.cog import MAX_LEVEL_BYTES, box_half, write_cog
from terratheme.core.exchange.geotiff import geotiff_tags
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.inputs import validate_region
from terratheme.core.render.project import photo_extent, render_georeference, render_project
from terratheme.core.render.renderer import RenderOptions

#: tile side of the file, and rows per rendered band
TILE = 512

Progress = Callable[[int, int], None]


def write_texture_tiff(
    project: ThematicTexture,
    path: str | os.PathLike,
    region: tuple[int, int, int, int] | None = None,
    *,
    options: RenderOptions | None = None,
    progress: Progress | None = None,
) -> tuple[tuple[int, int], int]:
    """Render ``region`` of a project into a tiled GeoTIFF with overviews, band by band.

    ``region`` (x, y, w, h) in texels defaults to the photo's extent, ``options`` to the
    project's style; ``progress(done, total)`` counts full-resolution bands. Returns the
    image's ``(w, h)`` and the number of overviews (each half the one before).
    """
    if region is None:
        region = (0, 0, *photo_extent(project))
    x, y, w, h = validate_region(region, project.grid.texture_size)
    if 3 * w * h > MAX_LEVEL_BYTES:
        raise OptionError(f"{path}: a {w} x {h} render is {3 * w * h / 2**30:.1f} GiB of "
                          f"pixels; the tiled GeoTIFF writer holds at most "
                          f"{MAX_LEVEL_BYTES / 2**30:.1f} GiB (classic TIFF levels): render "
                          "it in regions ({region})")
    bands = -(-h // TILE)
    done = [0]

    def band(y0: int, y1: int) -> np.ndarray:
        # Rows y0..y1 of the region, rendered as a whole render would render them.
        image = render_project(project, (x, y + y0, w, y1 - y0), options=options)
        done[0] += 1
        if progress is not None:
            progress(done[0], bands)
        return image

    tags = geotiff_tags(render_georeference(project, (x, y, w, h), (w, h)))
    levels = write_cog(path, band, (w, h), channels=3, tile=TILE, downsample=box_half,
                       extratags=tags)
    return (w, h), levels
