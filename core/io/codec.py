"""Images as bytes: WebP, JPEG, JPEG XL and PNG through OpenImageIO, AVIF through imagecodecs.

For small images inside another file (the colour map). AVIF is coded 4:4:4 with the BT.709
matrix (OpenImageIO's wheel writes no AVIF; docs/decisions.md). OpenImageIO reads and
writes files, so bytes pass through an unnamed ``O_TMPFILE`` the kernel frees however the
process ends (else a named temporary removed when done).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator

import imagecodecs
import numpy as np
import OpenImageIO as oiio
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.image_format import avif_size, error_line, jpegxl_size
from terratheme.core.io.images import write_oiio

#: codec name -> (file extension, OpenImageIO "Compression" attribute with {q} for the quality)
CODECS = {
    "webp": (".webp", "webp:{q}"),
    "jpeg": (".jpg", "jpeg:{q}"),
    "jpegxl": (".jxl", "jpegxl:{q}"),
    "png": (".png", "zip:9"),
    "avif": (".avif", ""),
}
#: libavif's encoder speed (0 slowest .. 10 fastest)
AVIF_SPEED = 6


#: OpenImageIO's format name of each codec
_FORMAT_NAMES = {"webp": "webp", "jpeg": "jpeg", "jpegxl": "jpegxl", "png": "png"}


@contextlib.contextmanager
def _scratch(ext: str) -> Iterator[tuple[int, str]]:
    """An empty read-write scratch file: its descriptor and a path OpenImageIO can open."""
    folder = tempfile.gettempdir()
    fd = None
    with contextlib.suppress(AttributeError, OSError):
        fd = os.open(folder, os.O_TMPFILE | os.O_RDWR, 0o600)
    named = fd is None or not os.path.exists(f"/proc/self/fd/{fd}")
    if named:
        if fd is not None:
            os.close(fd)
        fd, path = tempfile.mkstemp(suffix=ext, prefix="terratheme-codec-", dir=folder)
    else:
        path = f"/proc/self/fd/{fd}"
    try:
        yield fd, path
    finally:
        os.close(fd)
        if named:
            with contextlib.suppress(OSError):
                os.unlink(path)


def _read_all(fd: int) -> bytes:
    size, parts, done = os.fstat(fd).st_size, [], 0
    while done < size:
        part = os.pread(fd, size - done, done)
        if not part:
            break
        parts.append(part)
        done += len(part)
    return b"".join(parts)


def _codec(codec: str) -> tuple[str, str]:
    if codec not in CODECS:
        raise TerrathemeError(f"unknown image codec {codec!r}: use one of {', '.join(CODECS)}")
    return CODECS[codec]


def encode_image(pixels: np.ndarray, *, codec: str = "webp", quality: int = 80) -> bytes:
    """The bytes of an ``(h, w, 3)`` uint8 image in ``codec`` at ``quality`` (1..100).

    ``png`` is lossless and ignores the quality.
    """
    ext, attr = _codec(codec)
    arr = np.ascontiguousarray(pixels)
    if arr.ndim != 3 or arr.shape[2] not in (1, 3, 4) or arr.dtype != np.uint8 or not arr.size:
        raise TerrathemeError(f"encode_image needs an (h, w, 1|3|4) uint8 image, got "
                              f"{arr.shape} {arr.dtype}")
    if not 1 <= int(quality) <= 100:
        raise TerrathemeError(f"quality must be 1..100, got {quality}")
    if codec == "avif":
        return bytes(imagecodecs.avif_encode(
            arr[:, :, 0] if arr.shape[2] == 1 else arr, level=int(quality), speed=AVIF_SPEED,
            pixelformat=imagecodecs.AVIF.PIXEL_FORMAT.YUV444,
            matrix=imagecodecs.AVIF.MATRIX_COEFFICIENTS.BT709))
    with _scratch(ext) as (fd, path):
        spec = oiio.ImageSpec(arr.shape[1], arr.shape[0], arr.shape[2], "uint8")
        spec.attribute("Compression", attr.format(q=int(quality)))
        write_oiio("image" + ext, path, spec, arr, read_back=False)
        return _read_all(fd)


#: codecs whose image size :func:`check_header_shape` reads from the header alone
HEADER_SIZED = ("jpegxl", "avif")


def check_header_shape(data: bytes, codec: str, shape: tuple[int, int]) -> None:
    """Raise CorruptFileError unless a :data:`HEADER_SIZED` image's header says it is
    ``(h, w)`` = ``shape`` (nothing decoded)."""
    size = (jpegxl_size if codec == "jpegxl" else avif_size)(bytes(data[:1 << 14]))
    if size is None or (size[1], size[0]) != tuple(shape):
        found = "no size header" if size is None else f"{size[0]} x {size[1]}"
        raise CorruptFileError(f"{codec} image is {found}, expected {shape[1]} x {shape[0]}")


def decode_image(data: bytes, *, codec: str = "webp",
                 shape: tuple[int, int] | None = None) -> np.ndarray:
    """Pixels ``(h, w, C)`` uint8 of bytes written by :func:`encode_image`.

    ``shape``: the ``(h, w)`` the image must have; checked on its header before
    any pixel is decoded (a forged header cannot make it allocate more).
    """
    ext, _ = _codec(codec)
    if codec in HEADER_SIZED and shape is not None:
        # Both decode at once: check the header's size first.
        check_header_shape(data, codec, shape)
    if codec == "avif":
        try:
            pixels = imagecodecs.avif_decode(bytes(data))
        except imagecodecs.AvifError as exc:
            raise CorruptFileError(f"damaged avif image ({str(exc).splitlines()[0]})") from None
        return np.ascontiguousarray(pixels if pixels.ndim == 3 else pixels[:, :, None])
    with _scratch(ext) as (fd, path):
        with os.fdopen(os.dup(fd), "wb") as fh:
            fh.write(bytes(data))
        inp = oiio.ImageInput.open(path)
        if inp is None:
            raise CorruptFileError(f"not a {codec} image ({error_line()})")
        try:
            spec = inp.spec()
            if inp.format_name() != _FORMAT_NAMES[codec]:
                raise CorruptFileError(f"not a {codec} image (a {inp.format_name()} image)")
            if shape is not None and (spec.height, spec.width) != tuple(shape):
                raise CorruptFileError(f"{codec} image is {spec.width} x {spec.height}, "
                                       f"expected {shape[1]} x {shape[0]}")
            pixels = inp.read_image("uint8")
        finally:
            inp.close()
    if pixels is None or not hasattr(pixels, "ndim"):
        raise CorruptFileError(f"damaged {codec} image ({error_line()})")
    return np.ascontiguousarray(pixels if pixels.ndim == 3 else pixels[:, :, None])
