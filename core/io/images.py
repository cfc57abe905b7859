"""Image files in and out, all through OpenImageIO.

``read_image`` / ``write_image`` follow tifffile's style: a positional path and
keyword-only options. Arrays are always ``(H, W, C)`` when they go to
OpenImageIO: its Python ``write_image`` misreads 2-D arrays (DESIGN.md §5).

Writing goes to a temporary file that is renamed onto the target, so a failed
write never leaves a half-written image.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from core.errors import CorruptFileError, TerrathemeError
from core.io.atomic import atomic_path

#: numpy pixel types OpenImageIO stores, and their OpenImageIO type codes
OIIO_PIXEL_TYPES = {
    np.dtype(np.uint8): oiio.UINT8,
    np.dtype(np.uint16): oiio.UINT16,
    np.dtype(np.uint32): oiio.UINT32,
    np.dtype(np.int8): oiio.INT8,
    np.dtype(np.int16): oiio.INT16,
    np.dtype(np.int32): oiio.INT32,
    np.dtype(np.float16): oiio.HALF,
    np.dtype(np.float32): oiio.FLOAT,
    np.dtype(np.float64): oiio.DOUBLE,
}


@dataclass(frozen=True)
class ImageInfo:
    """What a file holds, read from its header only."""

    width: int
    height: int
    channels: int
    dtype: np.dtype
    tiled: bool
    tile_width: int
    tile_height: int
    format_name: str


def _open_input(path: str | os.PathLike) -> oiio.ImageInput:
    p = Path(path)
    if not p.exists():
        raise TerrathemeError(f"{p}: no such file")
    if p.is_dir():
        raise TerrathemeError(f"{p}: is a folder, not an image")
    inp = oiio.ImageInput.open(str(p))
    if inp is None:
        msg = oiio.geterror().strip().splitlines()
        why = msg[0] if msg else "unknown format"
        raise CorruptFileError(f"{p}: cannot read as an image ({why})")
    spec = inp.spec()
    if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
        inp.close()
        raise TerrathemeError(f"{p}: image has no pixels ({spec.width} x {spec.height})")
    return inp


def _np_dtype(spec: oiio.ImageSpec) -> np.dtype:
    for dt, td in OIIO_PIXEL_TYPES.items():
        if spec.format == oiio.TypeDesc(td):
            return dt
    return np.dtype(np.float32)


def image_info(path: str | os.PathLike) -> ImageInfo:
    """Read an image file's header: size, channels, pixel type, tiling."""
    inp = _open_input(path)
    try:
        spec = inp.spec()
        return ImageInfo(
            width=spec.width,
            height=spec.height,
            channels=spec.nchannels,
            dtype=_np_dtype(spec),
            tiled=spec.tile_width > 0,
            tile_width=spec.tile_width,
            tile_height=spec.tile_height,
            format_name=inp.format_name(),
        )
    finally:
        inp.close()


def read_image(path: str | os.PathLike, *, dtype: np.dtype | str | None = None) -> np.ndarray:
    """Read a whole image file.

    Parameters
    ----------
    path : path-like
        Any file OpenImageIO reads (PNG, JPEG, TIFF/BigTIFF, EXR, ...).
    dtype : numpy dtype, optional
        Convert to this pixel type (OpenImageIO rescales, e.g. uint16 -> uint8
        maps 65535 to 255). Default: the file's own type.

    Returns
    -------
    image : (H, W, C) ndarray
        Always three-dimensional; C is the file's channel count.

    Raises
    ------
    TerrathemeError
        Missing file, unreadable or truncated file, image with no pixels.
    """
    inp = _open_input(path)
    try:
        spec = inp.spec()
        want = np.dtype(dtype) if dtype is not None else _np_dtype(spec)
        pixels = inp.read_image(0, 0, 0, spec.nchannels, OIIO_PIXEL_TYPES.get(want, oiio.FLOAT))
        if pixels is None or inp.has_error:
            raise CorruptFileError(f"{path}: damaged or truncated image ({inp.geterror().strip()})")
    finally:
        inp.close()
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    return pixels.astype(want, copy=False).reshape(spec.height, spec.width, spec.nchannels)


def read_region(
    path: str | os.PathLike, x: int, y: int, w: int, h: int, *, dtype: np.dtype | str | None = None
) -> np.ndarray:
    """Read the ``w`` x ``h`` window at column ``x``, row ``y`` without reading the whole file.

    Tiled files are read tile by tile and scanline files line by line, so
    memory is bounded by the window, not the image.

    Returns
    -------
    window : (h, w, C) ndarray
    """
    inp = _open_input(path)
    try:
        spec = inp.spec()
        if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > spec.width or y + h > spec.height:
            raise TerrathemeError(
                f"{path}: window x={x} y={y} w={w} h={h} is outside the "
                f"{spec.width} x {spec.height} image"
            )
        want = np.dtype(dtype) if dtype is not None else _np_dtype(spec)
        fmt = OIIO_PIXEL_TYPES.get(want, oiio.FLOAT)
        if spec.tile_width > 0:
            tw, th = spec.tile_width, spec.tile_height
            x0, y0 = (x // tw) * tw, (y // th) * th
            x1 = min(-(-(x + w) // tw) * tw, spec.width + (-spec.width) % tw)
            y1 = min(-(-(y + h) // th) * th, spec.height + (-spec.height) % th)
            x1, y1 = min(x1, spec.width), min(y1, spec.height)
            block = inp.read_tiles(0, 0, x0, x1, y0, y1, 0, 1, 0, spec.nchannels, fmt)
            if block is None:
                raise CorruptFileError(f"{path}: damaged tiles ({inp.geterror().strip()})")
            block = np.asarray(block).reshape(y1 - y0, x1 - x0, spec.nchannels)
            out = block[y - y0 : y - y0 + h, x - x0 : x - x0 + w]
        else:
            rows = inp.read_scanlines(0, 0, y, y + h, 0, 0, spec.nchannels, fmt)
            if rows is None:
                raise CorruptFileError(f"{path}: damaged scanlines ({inp.geterror().strip()})")
            out = np.asarray(rows).reshape(h, spec.width, spec.nchannels)[:, x : x + w]
    finally:
        inp.close()
    return np.ascontiguousarray(out).astype(want, copy=False)


def write_image(
    path: str | os.PathLike,
    image: np.ndarray,
    *,
    tile: int | None = None,
    compression: str | None = None,
    attributes: dict[str, object] | None = None,
) -> None:
    """Write an image atomically (temporary file, then rename).

    Parameters
    ----------
    path : path-like
        Output file; the extension picks the format (.png, .jpg, .tif, .exr, ...).
    image : (H, W) or (H, W, C) ndarray
        Pixel data of any dtype OpenImageIO stores.
    tile : int, optional
        Write a tiled file (TIFF, EXR) with square tiles of this size.
    compression : str, optional
        OpenImageIO compression name, e.g. ``"zip"``, ``"lzw"``, ``"zip:9"``.
    attributes : dict, optional
        Extra metadata attributes for the ImageSpec (e.g. GeoTIFF tags).
    """
    arr = np.asarray(image)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[0] == 0 or arr.shape[1] == 0 or arr.shape[2] == 0:
        raise TerrathemeError(f"cannot write {path}: image shape {arr.shape} has no pixels")
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8) * 255
    if arr.dtype not in OIIO_PIXEL_TYPES:
        arr = arr.astype(np.float32)
    arr = np.ascontiguousarray(arr)
    h, w, c = arr.shape
    spec = oiio.ImageSpec(w, h, c, OIIO_PIXEL_TYPES[arr.dtype])
    if tile:
        spec.tile_width = spec.tile_height = int(tile)
    if compression:
        spec.attribute("compression", compression)
    for key, value in (attributes or {}).items():
        spec.attribute(key, value)
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(path))
        if out is None:
            why = oiio.geterror().strip() or "unknown format"
            raise TerrathemeError(f"cannot write {path}: {why}")
        if not out.open(str(tmp), spec):
            raise TerrathemeError(f"cannot write {path}: {out.geterror().strip()}")
        ok = out.write_image(arr)
        err = out.geterror().strip()
        out.close()
        if not ok:
            raise TerrathemeError(f"cannot write {path}: {err}")
