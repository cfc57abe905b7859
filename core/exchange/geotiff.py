"""GIS: the land-class map with a colour table and the baked texture, as georeferenced COG TIFFs.

At one pixel per texel over the photo's extent, so both carry the project's georeference
unchanged: ``landclass.tif`` (strongest theme by the export's style, palette of display
colours, with a QGIS ``landclass.qml``), ``texture.tif`` (the render), and
``colour_map.tif`` when the project has one. Tiled COGs (:mod:`.cog`), rendered band by band.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
from terratheme.core.errors import OptionError
from terratheme.core.exchange.cog import MAX_LEVEL_BYTES, box_half, nearest_half, write_cog
from terratheme.core.exchange.layout import world_frame
from terratheme.core.exchange.options import ExportOptions
from terratheme.core.exchange.plan import (
    CARRIED,
    ExportPlan,
    common_manifest,
    write_manifest,
)
from terratheme.core.exchange.style import export_boundary, export_render_options, map_labels
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.io.georef import tiff_extratags
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.project import photo_extent, render_georeference, render_project
from terratheme.core.render.renderer import render_labels

LANDCLASS, STYLE, TEXTURE, MANIFEST = "landclass.tif", "landclass.qml", "texture.tif", \
    "terratheme_geotiff.json"
#: the colour map's own pixels (gain x 128), georeferenced: one pixel per ``scale`` texels
COLOUR_TIFF = "colour_map.tif"
TILE = 512
#: GDAL tags describing the source photo's values (its no-data value would hide theme 0)
_SOURCE_VALUE_TAGS = ("GDAL_NODATA", "GDAL_METADATA")
Progress = Callable[[int, int], None]


def plan(project: ThematicTexture, options: ExportOptions) -> ExportPlan:
    """List the files of a GIS export (``size`` and ``tile`` are for engine maps)."""
    if options.size is not None or options.tile is not None:
        raise OptionError("the GeoTIFF export is at one pixel per texel, tiled inside the "
                          "file with overviews: {size} and {tile} are for engine exports")
    w, h = photo_extent(project)
    if 3 * w * h > MAX_LEVEL_BYTES:
        # Refused before any work: the baked texture is one pixel per texel.
        raise OptionError(
            f"the GIS export is one pixel per texel: a {w} x {h} texture is "
            f"{3 * w * h / 2**30:.1f} GiB of pixels, beyond the {MAX_LEVEL_BYTES / 2**30:.1f} "
            "GiB a GeoTIFF level holds here, and it takes no {size}: export the engine maps "
            "(--engine unity|unreal|godot {size} WxH), or bake parts with render --tiled "
            "--region")
    world = world_frame(project.metadata.get("georeference"), project.grid.texture_size)
    notes = () if project.metadata.get("georeference") else (
        "the project has no georeference (not made from a GeoTIFF): the TIFFs carry none",)
    colour = () if project.colour_map is None else (COLOUR_TIFF,)
    return ExportPlan(options, None, world,
                      (LANDCLASS, STYLE, TEXTURE, *colour, CARRIED, MANIFEST), notes)


def geotiff_tags(georeference: dict) -> list[tuple]:
    """tifffile ``extratags`` for the GeoTIFF tags of a georeference dict (placement only)."""
    return tiff_extratags({name: value for name, value in georeference.items()
                           if name not in _SOURCE_VALUE_TAGS})


def palette(project: ThematicTexture) -> np.ndarray:
    """``(3, 256)`` uint16 TIFF colour table: theme ``k``'s display colour at entry ``k``."""
    table = np.zeros((3, 256), dtype=np.uint16)
    table[:, : len(project.library)] = project.library.colours.T.astype(np.uint16) * 257
    return table


def qgis_style(project: ThematicTexture) -> str:
    """A QGIS layer style (``.qml``): the paletted renderer with every theme's colour and name."""
    entries = "\n".join(
        f'      <paletteEntry value="{k}" color="#{r:02x}{g:02x}{b:02x}" alpha="255" '
        f"label={quoteattr(t.name)}/>"
        for k, (t, (r, g, b)) in enumerate(zip(project.library, project.library.colours,
                                               strict=True)))
    return ("<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n"
            '<qgis version="3.28" styleCategories="Symbology">\n <pipe>\n'
            '  <rasterrenderer type="paletted" band="1" opacity="1" alphaBand="-1">\n'
            f"   <colorPalette>\n{entries}\n   </colorPalette>\n"
            "  </rasterrenderer>\n </pipe>\n</qgis>\n")


def write(project: ThematicTexture, plan: ExportPlan, folder: Path,
          progress: Progress | None = None) -> None:
    """Write the land-class map, its QGIS style, the baked texture and the manifest."""
    w, h = photo_extent(project)
    tags = geotiff_tags(render_georeference(project, (0, 0, w, h), (w, h)))
    grid, cell, k = project.grid.indices, project.grid.cell, len(project.library)
    saddle = plan.options.saddle
    shaped = export_boundary(project, plan.options) is not None
    render_options = export_render_options(project, plan.options)
    # Class-map pixel i is texel i: a map of Wtex + 1 pixels (the renderer's texels).
    texels = (project.grid.texture_size[0] + 1, project.grid.texture_size[1] + 1)
    bands = -(-h // TILE)
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress:
            progress(done[0], 2 * bands)

    def labels(y0: int, y1: int) -> np.ndarray:
        tick()
        if shaped:
            return map_labels(project, texels, (0, y0, w, y1 - y0), plan.options)
        return render_labels(grid, cell, (0, y0, w, y1 - y0), n_themes=k, saddle=saddle)

    def texture(y0: int, y1: int) -> np.ndarray:
        tick()
        return render_project(project, (0, y0, w, y1 - y0), options=render_options)

    levels = write_cog(folder / LANDCLASS, labels, (w, h), channels=1, tile=TILE,
                       photometric="minisblack", colormap=palette(project),
                       downsample=nearest_half, extratags=tags)
    write_bytes_atomic(folder / STYLE, qgis_style(project).encode())
    write_cog(folder / TEXTURE, texture, (w, h), channels=3, tile=TILE, downsample=box_half,
              extratags=tags)
    cmap = project.colour_map
    if cmap is not None:
        # Map pixel i covers texels i s .. (i + 1) s (core.render.colour_map).
        mh, mw = cmap.pixels.shape[:2]
        ctags = geotiff_tags(render_georeference(project, (0, 0, mw * cmap.scale,
                                                           mh * cmap.scale), (mw, mh)))
        write_cog(folder / COLOUR_TIFF, lambda y0, y1: cmap.pixels[y0:y1], (mw, mh),
                  channels=3, tile=TILE, downsample=box_half, extratags=ctags)
    manifest = common_manifest(project, plan, None if cmap is None else COLOUR_TIFF)
    if manifest["colour_map"] is not None:
        manifest["colour_map"]["baked_into"] = TEXTURE
    manifest.update({
        "landclass": LANDCLASS, "style": STYLE, "texture": TEXTURE, "size": [w, h],
        "tile": TILE, "overviews": levels, "georeferenced": bool(tags),
        "classes": [{"value": j, "name": t.name, "colour": list(t.colour)}
                    for j, t in enumerate(project.library)],
    })
    write_manifest(folder / MANIFEST, manifest)
