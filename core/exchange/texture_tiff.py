"""A render larger than memory: a tiled GeoTIFF with overviews, written band by band.

``terratheme render PROJECT OUT.tif`` of a whole region cannot hold the image
(a 400 x 400 km region at 1 m is 480 GB of RGB). :func:`write_texture_tiff`
renders ``TILE``-row bands of the region (``core.render.project.render_project``,
the project's style and colour map: the same texels as a whole render) and
hands them to :func:`core.exchange.cog.write_cog`, which writes them as
deflate-compressed tiles, makes each overview from the level before it read
back band by band (2 x 2 means: the exact box filter of the rendered
texels), and lays the file out as a Cloud Optimized GeoTIFF. The
georeference is the render's (``core.render.project.render_georeference``).

Memory is set by one band (``TILE`` rows of the region's width: 48 MiB at
32768 texels wide), never by the height; the disk needs about twice the
output while the levels are laid out. ``write_cog`` writes each level as a
classic TIFF first, so a level of more than :data:`MAX_LEVEL_BYTES` of raw
pixels (about 37,700 x 37,700 RGB) is refused before any work until it writes
those as BigTIFF.
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

    Parameters
    ----------
    project : ThematicTexture
    path : path-like
        ``.tif`` output, written atomically (BigTIFF when its tiles pass 4 GiB).
    region : (x, y, w, h), optional
        Full-resolution texels; default the photo's extent
        (:func:`core.render.project.photo_extent`).
    options : RenderOptions, optional
        Default: the project's own style.
    progress : callable(done, total), optional
        Over the bands of the full-resolution level.

    Returns
    -------
    size : (w, h) of the full-resolution image
    overviews : int
        Reduced levels after it (each half the one before, down to one tile).
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
