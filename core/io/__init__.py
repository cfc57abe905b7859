"""Files in and out: images, tiles of images larger than memory, georeference, atomic writes.

One module a job: ``images``, ``tiles``, ``cluster``, ``tiled_writer``, ``georef``,
``atomic``, ``codec``, ``archive``, ``png``, ``memory``, ``disk_cache``, ``inputs``.
"""

from terratheme.core.io.atomic import (
    atomic_path,
    file_set,
    remove_temporaries,
    write_bytes_atomic,
)
from terratheme.core.io.cluster import connect, local_cluster, map_ordered
from terratheme.core.io.codec import decode_image, encode_image
from terratheme.core.io.georef import (
    read_georeference,
    scale_georeference,
    validate_georeference,
    write_georeference,
)
from terratheme.core.io.images import (
    Bands,
    ImageInfo,
    image_attributes,
    image_info,
    read_image,
    read_labels,
    read_region,
    read_windows,
    write_image,
)
from terratheme.core.io.memory import available_memory, check_fits
from terratheme.core.io.tiled_writer import TiledImageWriter
from terratheme.core.io.tiles import (
    Scheduler,
    TileWindow,
    run_tiles,
    tile_windows,
)

__all__ = [
    "Bands",
    "ImageInfo",
    "Scheduler",
    "TileWindow",
    "TiledImageWriter",
    "atomic_path",
    "available_memory",
    "check_fits",
    "connect",
    "decode_image",
    "encode_image",
    "file_set",
    "image_attributes",
    "image_info",
    "local_cluster",
    "map_ordered",
    "read_georeference",
    "read_image",
    "read_labels",
    "read_region",
    "read_windows",
    "remove_temporaries",
    "run_tiles",
    "scale_georeference",
    "tile_windows",
    "validate_georeference",
    "write_bytes_atomic",
    "write_georeference",
    "write_image",
]
