"""Image files in and out, all through OpenImageIO.

Arrays are always ``(H, W, C)`` when they go to OpenImageIO (its Python
``write_image`` misreads 2-D arrays) and alpha is never premultiplied or divided
(``oiio:UnassociatedAlpha``, design.md §9). Hostile files are refused before any
pixel is read: declared size against the bytes present
(:data:`MAX_COMPRESSION_RATIO`) and OpenImageIO's limits, PNG chunks checked
before libpng sees them. Writes go through :func:`atomic_path`, so a failed write
leaves no half-written image; ``palette=`` makes an 8-bit label image a palette PNG.
"""

from __future__ import annotations

import contextlib
import enum
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.atomic import atomic_path
from terratheme.core.io.image_format import (
    NO_FILE_FORMATS,
    error_line,
    first_line,
    jpegxl_file_size,
)
from terratheme.core.io.inputs import check_input_file
from terratheme.core.io.png import (
    check_palette,
    check_png_chunks,
    is_png,
    palette_indices,
    png_header_size,
    png_palette,
    relabel_grey_png_as_palette,
)
from terratheme.core.io.tiff_check import check_tiff_chunks

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
#: most bytes of pixels a file may declare per byte it holds (deflate's limit is 1032)
MAX_COMPRESSION_RATIO = 2048
#: declared pixel bytes always allowed, whatever the file size
MIN_DECLARED_BYTES = 4 << 20
#: most channels an image may have (OpenImageIO's limits:channels is set to this)
MAX_CHANNELS = 64

oiio.attribute("limits:channels", MAX_CHANNELS)


class Bands(enum.Enum):
    """Which channels of a file are read."""

    ALL = "all"      # every channel, as stored
    PHOTO = "photo"  # grey or RGB, plus alpha only where the file marks one, last


@dataclass(frozen=True)
class ImageInfo:
    """What a file holds, read from its header only.

    ``alpha_channel`` is the channel the file marks as alpha, or -1.
    """

    width: int
    height: int
    channels: int
    dtype: np.dtype
    tiled: bool
    tile_width: int
    tile_height: int
    format_name: str
    alpha_channel: int = -1

    def band_indices(self, bands: Bands) -> list[int]:
        """The channels :class:`Bands` selects, in output order."""
        if bands is Bands.ALL:
            return list(range(self.channels))
        colour = [0] if self.channels < 3 or self.alpha_channel in (1, 2) else [0, 1, 2]
        alpha = [self.alpha_channel] if self.alpha_channel >= len(colour) else []
        return colour + alpha


def _open_input(path: str | os.PathLike) -> oiio.ImageInput:
    p = check_input_file(path, "an image")
    size = png_header_size(p) or jpegxl_file_size(p)
    if size is not None and (size[0] == 0 or size[1] == 0):
        raise TerrathemeError(f"{p}: image has no pixels ({size[0]} x {size[1]})")
    if size is not None:  # a byte a pixel at least; OpenImageIO decodes JPEG XL in open()
        _check_declared(p, size[0], size[1], 1, size[0] * size[1])
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    if is_png(p):
        check_png_chunks(p)  # before libpng, which prints its own errors on stderr
    inp = oiio.ImageInput.open(str(p), config)
    if inp is None:
        why = error_line() or "unknown format"
        raise CorruptFileError(f"{p}: cannot read as an image ({why})")
    if inp.format_name() in NO_FILE_FORMATS:
        # OpenImageIO's null reader makes pixels from the name ('x.null?RES=64x64'), not
        # from the file's bytes.
        inp.close()
        raise CorruptFileError(f"{p}: not an image file (OpenImageIO's "
                               f"{inp.format_name()} format takes its pixels from the name)")
    spec = inp.spec()
    if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
        inp.close()
        raise TerrathemeError(f"{p}: image has no pixels ({spec.width} x {spec.height})")
    if spec.deep:
        inp.close()
        raise TerrathemeError(f"{p}: deep images are not supported")
    try:
        _check_declared(p, spec.width, spec.height, spec.nchannels, int(spec.image_bytes()))
        if spec.tile_width > 0:
            # One tile is decoded whole: its declared size is bounded as the image's.
            tile = spec.tile_width * spec.tile_height * max(1, spec.tile_depth)
            _check_declared(p, spec.tile_width, spec.tile_height, spec.nchannels,
                            tile * int(spec.pixel_bytes()))
    except CorruptFileError:
        inp.close()
        raise
    if inp.format_name() == "tiff":
        try:
            check_tiff_chunks(p)
        except CorruptFileError:
            inp.close()
            raise
    return inp


def _check_declared(p: Path, width: int, height: int, channels: int, declared: int) -> None:
    """Refuse a header declaring more pixel bytes than the file can hold."""
    allowed = MAX_COMPRESSION_RATIO * p.stat().st_size + MIN_DECLARED_BYTES
    if declared > allowed:
        raise CorruptFileError(
            f"{p}: header declares {width} x {height} x {channels} pixels "
            f"({declared / 2**20:,.0f} MiB) from a {p.stat().st_size:,}-byte file: damaged "
            "or forged")


def _np_dtype(spec: oiio.ImageSpec) -> np.dtype:
    for dt, td in OIIO_PIXEL_TYPES.items():
        if spec.format == oiio.TypeDesc(td):
            return dt
    return np.dtype(np.float32)


def _alpha_channel(spec: oiio.ImageSpec) -> int:
    """The alpha channel's index, or -1 (past the last one, as GIF's 4 of RGBA: the one named A)."""
    if 0 <= spec.alpha_channel < spec.nchannels:
        return spec.alpha_channel
    names = list(spec.channelnames)
    return names.index("A") if spec.alpha_channel >= 0 and "A" in names else -1


def _info(inp: oiio.ImageInput) -> ImageInfo:
    spec = inp.spec()
    return ImageInfo(width=spec.width, height=spec.height, channels=spec.nchannels,
                     dtype=_np_dtype(spec), tiled=spec.tile_width > 0,
                     tile_width=spec.tile_width, tile_height=spec.tile_height,
                     format_name=inp.format_name(), alpha_channel=_alpha_channel(spec))


def image_info(path: str | os.PathLike) -> ImageInfo:
    """Read an image file's header: size, channels, pixel type, tiling, alpha."""
    inp = _open_input(path)
    try:
        return _info(inp)
    finally:
        inp.close()


def image_attributes(path: str | os.PathLike, prefix: str) -> dict[str, object]:
    """The header attributes whose names start with ``prefix`` (case-insensitive)."""
    inp = _open_input(path)
    try:
        return {a.name: a.value for a in inp.spec().extra_attribs
                if a.name.lower().startswith(prefix.lower())}
    finally:
        inp.close()


def _select(pixels: np.ndarray, info: ImageInfo, bands: Bands, first: int) -> np.ndarray:
    keep = info.band_indices(bands)
    if keep == list(range(first, first + pixels.shape[2])):
        return pixels
    return pixels[:, :, [k - first for k in keep]]


def read_image(path: str | os.PathLike, *, dtype: np.dtype | str | None = None,
               bands: Bands = Bands.ALL) -> np.ndarray:
    """Read a whole image file as (H, W, C), alpha as stored (never premultiplied).

    ``dtype`` converts (OpenImageIO rescales: uint16 65535 -> uint8 255; default the file's
    own); ``bands`` ALL: every channel, PHOTO: colour plus marked alpha.
    """
    inp = _open_input(path)
    try:
        info = _info(inp)
        keep = info.band_indices(bands)
        first, last = min(keep), max(keep) + 1
        want = np.dtype(dtype) if dtype is not None else info.dtype
        try:
            pixels = inp.read_image(0, 0, first, last, OIIO_PIXEL_TYPES.get(want, oiio.FLOAT))
        except MemoryError:
            raise TerrathemeError(f"{path}: not enough memory to read {info.width} x "
                                  f"{info.height} x {info.channels} pixels") from None
        if pixels is None or inp.has_error:
            raise CorruptFileError(
                f"{path}: damaged or truncated image ({error_line(inp) or 'no reason given'})")
    finally:
        inp.close()
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    pixels = pixels.astype(want, copy=False).reshape(info.height, info.width, last - first)
    return _select(pixels, info, bands, first)


def read_bands(path: str | os.PathLike, rows: int, *, dtype: np.dtype | str | None = None
               ) -> Iterator[tuple[int, np.ndarray]]:
    """``(y, band)`` pairs of a whole image, top to bottom, from one opening of the file.

    Memory is one band of ``rows`` rows (the last may be shorter), shape
    ``(h, W, C)``; a PNG is decoded once (:func:`read_windows`), not once per band as
    :func:`read_region` calls would.
    """
    info = image_info(path)
    step = max(1, int(rows))
    tops = range(0, info.height, step)
    boxes = [(0, y, info.width, min(step, info.height - y)) for y in tops]
    with contextlib.closing(read_windows(path, boxes, dtype=dtype)) as bands:
        yield from zip(tops, bands, strict=True)


def read_region(
    path: str | os.PathLike, x: int, y: int, w: int, h: int, *,
    dtype: np.dtype | str | None = None, bands: Bands = Bands.ALL,
) -> np.ndarray:
    """Read the (h, w, C) window at column ``x``, row ``y`` without reading the whole file.

    Tiled files are read tile by tile and scanline files line by line, so memory is
    bounded by the window. ``bands`` as :func:`read_image`.
    """
    with contextlib.closing(read_windows(path, [(x, y, w, h)], dtype=dtype, bands=bands)) as got:
        return next(got)


def read_windows(
    path: str | os.PathLike, windows: Iterable[tuple[int, int, int, int]], *,
    dtype: np.dtype | str | None = None, bands: Bands = Bands.ALL,
) -> Iterator[np.ndarray]:
    """The (h, w, C) pixels of each (x, y, w, h) window in turn, from one opening of the file.

    Tiled files are read tile by tile. Scanline files are read top to bottom, the rows a
    later window shares kept: windows in order of their top row decode a JPEG or PNG (no
    random access: a window at row y costs the y rows above it) once, not once per
    window; a window above the rows kept reopens the file. Memory: the full-width rows of
    one window. ``bands`` as :func:`read_image`.
    """
    inp = _open_input(path)
    try:
        spec = inp.spec()
        info = _info(inp)
        keep = info.band_indices(bands)
        first, last = min(keep), max(keep) + 1
        want = np.dtype(dtype) if dtype is not None else info.dtype
        fmt = OIIO_PIXEL_TYPES.get(want, oiio.FLOAT)
        kept, top = None, 0  # scanline files: full-width rows from row ``top``
        for x, y, w, h in windows:
            if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > spec.width or y + h > spec.height:
                raise TerrathemeError(
                    f"{path}: window x={x} y={y} w={w} h={h} is outside the "
                    f"{spec.width} x {spec.height} image"
                )
            if spec.tile_width > 0:
                tw, th = spec.tile_width, spec.tile_height
                x0, y0 = (x // tw) * tw, (y // th) * th
                x1 = min(-(-(x + w) // tw) * tw, spec.width)
                y1 = min(-(-(y + h) // th) * th, spec.height)
                block = inp.read_tiles(0, 0, x0, x1, y0, y1, 0, 1, first, last, fmt)
                if block is None or inp.has_error:
                    raise CorruptFileError(
                        f"{path}: damaged tiles ({error_line(inp) or 'no reason given'})")
                block = np.asarray(block).reshape(y1 - y0, x1 - x0, last - first)
                out = block[y - y0 : y - y0 + h, x - x0 : x - x0 + w]
            else:
                if kept is not None and y < top:
                    # Above the rows kept: the decoder starts again from the top.
                    inp.close()
                    inp, kept = _open_input(path), None
                end = top + (0 if kept is None else len(kept))
                # Rows above the window dropped; the rows below the kept ones read on.
                kept = kept[y - top:] if kept is not None and y < end else None
                start = y if kept is None else end
                top = y
                if y + h > start:
                    rows = inp.read_scanlines(0, 0, start, y + h, 0, first, last, fmt)
                    if rows is None or inp.has_error:
                        raise CorruptFileError(f"{path}: damaged or truncated image "
                                               f"({error_line(inp) or 'no reason given'})")
                    rows = np.asarray(rows).reshape(y + h - start, spec.width, last - first)
                    kept = rows if kept is None else np.concatenate([kept, rows])
                out = kept[:h, x : x + w]
            # A compact copy: never a view of rows kept for a later window.
            out = out.astype(want, order="C")
            yield np.ascontiguousarray(_select(out, info, bands, first))
    finally:
        inp.close()


def read_labels(path: str | os.PathLike) -> np.ndarray:
    """Class numbers stored in an image file, as an ``(H, W)`` integer array.

    A palette PNG gives its palette indices; other files must hold one channel,
    or channels that are all equal (a grey image saved as RGB).
    """
    image = read_image(path)
    palette = png_palette(path)
    if palette is not None:
        return palette_indices(image, palette, path)
    if image.shape[2] > 1 and not all(np.array_equal(image[:, :, 0], image[:, :, c])
                                      for c in range(1, image.shape[2])):
        raise TerrathemeError(f"{path}: a label image must hold single-channel class values, "
                              f"not a {image.shape[2]}-channel colour image")
    if not np.issubdtype(image.dtype, np.integer):
        raise TerrathemeError(f"{path}: label values must be whole numbers, not {image.dtype}")
    return np.ascontiguousarray(image[:, :, 0])


def read_class_mask(path: str | os.PathLike) -> np.ndarray:
    """:func:`read_labels` of a class mask (scribbles, training labels): ``(H, W)`` uint8,
    values 0..255 (0 unlabelled), else TerrathemeError."""
    mask = read_labels(path)
    if mask.size and (int(mask.max()) > 255 or int(mask.min()) < 0):
        raise TerrathemeError(f"{path}: class mask values must be whole numbers 0..255")
    return mask.astype(np.uint8)


def write_image(
    path: str | os.PathLike,
    image: np.ndarray,
    *,
    tile: int | None = None,
    compression: str | None = None,
    attributes: dict[str, object] | None = None,
    palette: np.ndarray | None = None,
) -> None:
    """Write an image atomically (temporary file, then rename).

    ``image``: (H, W) or (H, W, C), any dtype OpenImageIO stores; 2 or 4 channels carry
    unassociated alpha last. ``tile``: square tiles (TIFF, EXR); ``compression``: an
    OpenImageIO name such as ``"zip:9"``; ``attributes``: extra ImageSpec attributes (GeoTIFF
    tags); ``palette`` (K, 3) uint8: a single-channel uint8 PNG becomes a palette PNG.
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
    if palette is not None:
        palette = check_palette(path, arr, palette)
    arr = np.ascontiguousarray(arr)
    h, w, c = arr.shape
    spec = oiio.ImageSpec(w, h, c, OIIO_PIXEL_TYPES[arr.dtype])
    spec.attribute("oiio:UnassociatedAlpha", 1)
    if tile:
        spec.tile_width = spec.tile_height = int(tile)
    if compression:
        spec.attribute("compression", compression)
    for key, value in (attributes or {}).items():
        spec.attribute(key, value)
    with atomic_path(path) as tmp:
        write_oiio(path, tmp, spec, arr)
        if palette is not None:
            relabel_grey_png_as_palette(tmp, palette)


#: writers that must not meet a full disk: libjpeg ends the process, the WebP writer
#: never returns (OpenImageIO 3.2); they need this many bytes free per pixel byte
SPACE_BOUND = {"jpeg": 2, "webp": 2}
#: OpenImageIO's text for a short write (its file layer reports it, some writers go on)
_SHORT_WRITE = ("write error", "could only write")


def _check_space(path: str | os.PathLike, tmp: Path, fmt: str, nbytes: int) -> None:
    if fmt not in SPACE_BOUND:
        return
    try:
        st = os.statvfs(tmp)
    except OSError:
        return
    need = SPACE_BOUND[fmt] * nbytes + (1 << 16)
    if st.f_bavail * st.f_frsize < need:
        raise TerrathemeError(f"cannot write {path}: {st.f_bavail * st.f_frsize:,} bytes free "
                              f"on its disk, a {fmt} image of this size may need {need:,}")


def _error_text(out: oiio.ImageOutput) -> str:
    try:
        return out.geterror()
    except UnicodeDecodeError:
        return "an error whose text is not UTF-8"


def write_oiio(path: str | os.PathLike, tmp: str | os.PathLike, spec: oiio.ImageSpec,
               pixels: np.ndarray, *, read_back: bool = True) -> None:
    """Write ``(H, W, C)`` ``pixels`` to ``tmp`` in ``path``'s format, every step checked.

    A failed write (a full disk) is a False from ``write_image`` or ``close``,
    or for some writers only a short-write error on the writer: any raises; so does a
    file that does not read back on a nearly full disk (:func:`check_written`; not for a
    ``tmp`` named without ``path``'s suffix: ``read_back=False``).
    """
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise TerrathemeError(f"cannot write {path}: {error_line() or 'unknown format'}")
    _check_space(path, Path(tmp), out.format_name(), pixels.nbytes)
    if not out.open(str(tmp), spec):
        raise TerrathemeError(f"cannot write {path}: {open_failure(path, tmp, out)}")
    ok = out.write_image(pixels)
    errors = _error_text(out)
    ok = out.close() and ok
    errors += _error_text(out)
    if not ok or any(s in errors.lower() for s in _SHORT_WRITE):
        why = first_line(errors) or error_line() or "the file could not be finished"
        raise TerrathemeError(f"cannot write {path}: {why}")
    if read_back:
        check_written(path, tmp)


#: free bytes on its disk (or two of its blocks, if more) below which a written image is
#: read back: OpenImageIO's file layer drops the error of its last buffered write (at
#: fclose, one block at most), so a full disk can cut the file's end (a small EXR, PNG,
#: BMP to 0 bytes) with every call reporting success
READ_BACK_BELOW = 64 << 10
#: most bytes of pixels held at once while reading back
_READ_BACK_BAND = 16 << 20


def _nearly_full(path: str | os.PathLike) -> int | None:
    """The free bytes of ``path``'s disk when under :data:`READ_BACK_BELOW` (or two of its
    blocks, if more), else None (None too when the disk cannot be asked)."""
    try:
        st = os.statvfs(path)
    except OSError:
        return None
    free = st.f_bavail * st.f_frsize
    return free if free < max(READ_BACK_BELOW, 2 * st.f_bsize) else None


def open_failure(path: str | os.PathLike, tmp: str | os.PathLike,
                 out: oiio.ImageOutput) -> str:
    """Why ``out`` could not open ``tmp`` (``path``'s temporary): its disk is full (libtiff
    says 'Could not open' of a header it cannot write), or OpenImageIO's text, the
    temporary named as ``path``."""
    why = (error_line(out) or error_line()).replace(str(tmp), str(path))  # read: cleared
    free = _nearly_full(Path(tmp).parent)
    return why if free is None else f"its disk is full ({free:,} bytes free)"


def check_written(path: str | os.PathLike, tmp: str | os.PathLike) -> None:
    """Refuse ``tmp`` (``path``'s image, just written by OpenImageIO) that does not read
    back whole, when its disk is nearly full (:data:`READ_BACK_BELOW`); memory one band."""
    if _nearly_full(tmp) is None:
        return
    try:
        info = image_info(tmp)
        row = info.width * info.channels * info.dtype.itemsize
        for _ in read_bands(tmp, max(1, _READ_BACK_BAND // row)):
            pass
    except TerrathemeError:
        raise TerrathemeError(f"cannot write {path}: its disk is full (the file written does "
                              "not read back whole)") from None
