"""A packed layer written out as an image file, band by band (``terratheme unpack``).

An index layer's ``.png`` is a streamed palette PNG, ``.tif``/``.exr`` a streamed tiled
file (memory: one band whatever the layer's size); anything else is written whole, up
to :data:`WHOLE_IMAGE_TEXELS`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import write_image
from terratheme.core.io.tiled_writer import TiledImageWriter
from terratheme.core.packing.index_png import PalettePngWriter, display_colours

#: Largest layer written whole (formats with no streamed writer): 256 Mi texels.
WHOLE_IMAGE_TEXELS = 1 << 28
#: Rows per band (also the tile size of streamed TIFF/EXR files); layers wider than
#: 65536 texels use a quarter of that, so a band stays within 16 MiB per 256 Ki texels.
BAND_ROWS = 256
TILED_SUFFIXES = (".tif", ".tiff", ".exr")


class BandedLayer(Protocol):
    """What :func:`write_layer_image` needs of a layer (PackedLayer and TiledLayer)."""

    width: int
    height: int
    identity: bool
    palette: np.ndarray
    colours: np.ndarray | None

    def bands(self, rows: int = ...): ...

    def values_of(self, indices: np.ndarray) -> np.ndarray: ...

    @property
    def channels(self) -> int: ...


#: Image formats that store values approximately: a layer's indices or values would change.
LOSSY_SUFFIXES = frozenset({".jpg", ".jpeg", ".jpe", ".jfif", ".webp", ".heic", ".heif",
                            ".avif", ".jxr"})


#: Image formats OpenImageIO does not give back as written, and why.
INEXACT_SUFFIXES = {".rla": "OpenImageIO changes their last column",
                    ".zfile": "they hold depths, as floats scaled to 0..1"}


#: Image formats that keep 16-bit values (OpenImageIO scales them to 8 bits in BMP and TGA,
#: halves them into signed 16 bits in FITS).
WIDE_SUFFIXES = frozenset({".png", ".tif", ".tiff", ".exr", ".dpx", ".jxl", ".sgi", ".pgm",
                           ".ppm", ".pnm", ".tx"})


def check_layer_image_path(path: str | os.PathLike, what: str = "the layer's values") -> None:
    """Refuse (TerrathemeError) a lossy output format, :data:`LOSSY_SUFFIXES`, or one that
    does not read back as written, :data:`INEXACT_SUFFIXES`, before any work; ``what`` the
    message says would change."""
    suffix = Path(path).suffix.lower()
    if suffix in LOSSY_SUFFIXES:
        raise TerrathemeError(f"{path}: {suffix} images are lossy and would change {what}; "
                              "write .png, .tif or .exr")
    if suffix in INEXACT_SUFFIXES:
        raise TerrathemeError(f"{path}: {suffix} images do not read back as written "
                              f"({INEXACT_SUFFIXES[suffix]}), which would change {what}; write "
                              ".png, .tif or .exr")


def write_layer_image(
    layer: BandedLayer, path: str | os.PathLike, *,
    progress: Callable[[int, int], None] | None = None,
) -> str:
    """Write ``layer`` to the image file ``path`` atomically, choosing by extension.

    Returns what was written: ``"palette PNG"``, ``"tiled image"`` or ``"image"``.
    Raises TerrathemeError for a lossy format, a layer too large for a format written
    whole, or a write failure.
    """
    check_layer_image_path(path)
    suffix = Path(path).suffix.lower()
    if layer.palette.dtype.itemsize > 1 and suffix not in WIDE_SUFFIXES:
        raise TerrathemeError(f"{path}: {suffix} images do not keep the layer's "
                              f"{layer.palette.dtype} values; write .png, .tif or .exr")
    texels = layer.width * layer.height
    rows = BAND_ROWS if layer.width <= 65536 else BAND_ROWS // 4
    palette_png = suffix == ".png" and layer.identity and layer.palette.dtype == np.uint8
    if palette_png:
        colours = layer.colours if layer.colours is not None else display_colours(
            len(layer.palette))
        # zlib's fastest level past WHOLE_IMAGE_TEXELS (docs/decisions.md).
        level = 6 if texels <= WHOLE_IMAGE_TEXELS else 1
        with PalettePngWriter(path, layer.width, layer.height, colours, level=level) as out:
            for y, band in layer.bands(rows):
                out.write_rows(band)
                _report(progress, y + band.shape[0], layer.height)
        return "palette PNG"
    if suffix in TILED_SUFFIXES:
        big = texels * layer.channels * layer.palette.dtype.itemsize > (1 << 31)
        # EXR has no 8- or 16-bit integers: OpenImageIO stored them as half floats scaled
        # to 0..1, which merged uint16 values (60000 and 60001); its 32-bit UINT keeps them.
        dtype = np.uint32 if suffix == ".exr" else layer.palette.dtype
        with TiledImageWriter(path, layer.width, layer.height, layer.channels,
                              dtype, tile=rows, bigtiff=big) as out:
            for y, band in layer.bands(rows):
                out.write(0, y, layer.values_of(band))
                _report(progress, y + band.shape[0], layer.height)
        return "tiled image"
    if texels > WHOLE_IMAGE_TEXELS:
        raise TerrathemeError(
            f"{path}: a {layer.width} x {layer.height} layer is written band by band only "
            "as .png (index layers) or .tif/.exr; choose one of those")
    image = np.empty((layer.height, layer.width), np.uint8)
    for y, band in layer.bands(BAND_ROWS):
        image[y: y + band.shape[0]] = band
    write_image(path, layer.values_of(image))
    _report(progress, layer.height, layer.height)
    return "image"


def _report(progress: Callable[[int, int], None] | None, done: int, total: int) -> None:
    if progress is not None:
        progress(done, total)
