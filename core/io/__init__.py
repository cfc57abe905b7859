"""Files in and out: images, tiles of images larger than memory, georeference, atomic writes.

Modules: ``images`` (every image file through OpenImageIO), ``tiles`` (tile
windows, bounded-memory tile jobs on one machine or Dask, tiled writing),
``georef`` (GeoTIFF tags and world files), ``atomic`` (write to a temporary
file, then rename).
"""

from core.io.atomic import atomic_path, write_bytes_atomic
from core.io.georef import read_georeference, scale_georeference, write_georeference
from core.io.images import ImageInfo, image_info, read_image, read_region, write_image
from core.io.tiles import (
    Scheduler,
    TiledImageWriter,
    TileWindow,
    map_tiles,
    run_tiles,
    tile_windows,
)

__all__ = [
    "ImageInfo",
    "Scheduler",
    "TileWindow",
    "TiledImageWriter",
    "atomic_path",
    "image_info",
    "map_tiles",
    "read_georeference",
    "read_image",
    "read_region",
    "run_tiles",
    "scale_georeference",
    "tile_windows",
    "write_bytes_atomic",
    "write_georeference",
    "write_image",
]
