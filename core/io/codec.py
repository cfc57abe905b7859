"""Images as bytes: encode and decode through OpenImageIO's codecs (WebP, JPEG, JPEG XL, PNG).

Used where a small image travels inside another file or is counted in bytes
(the colour map of a thematic texture). OpenImageIO's Python API reads and
writes files, so the bytes pass through a private temporary file.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.image_format import error_line, jpegxl_size

#: codec name -> (file extension, OpenImageIO "Compression" attribute with {q} for the quality)
CODECS = {
    "webp": (".webp", "webp:{q}"),
    "jpeg": (".jpg", "jpeg:{q}"),
    "jpegxl": (".jxl", "jpegxl:{q}"),
    "png": (".png", "zip:9"),
}


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
    with tempfile.TemporaryDirectory(prefix="terratheme-codec-") as folder:
        path = os.path.join(folder, "image" + ext)
        out = oiio.ImageOutput.create(path)
        spec = oiio.ImageSpec(arr.shape[1], arr.shape[0], arr.shape[2], "uint8")
        spec.attribute("Compression", attr.format(q=int(quality)))
        if out is None or not out.open(path, spec) or not out.write_image(arr) or not out.close():
            raise TerrathemeError(f"cannot encode a {codec} image: {error_line()}")
        return Path(path).read_bytes()


def decode_image(data: bytes, *, codec: str = "webp",
                 shape: tuple[int, int] | None = None) -> np.ndarray:
    """Pixels ``(h, w, C)`` uint8 of bytes written by :func:`encode_image`.

    ``shape``: the ``(h, w)`` the image must have; checked on its header before
    any pixel is decoded (a forged header cannot make it allocate more).
    """
    ext, _ = _codec(codec)
    if codec == "jpegxl" and shape is not None:
        # OpenImageIO decodes JPEG XL inside open(): check the header's size first.
        size = jpegxl_size(bytes(data[:1 << 12]))
        if size is None or (size[1], size[0]) != tuple(shape):
            found = "no size header" if size is None else f"{size[0]} x {size[1]}"
            raise CorruptFileError(f"jpegxl image is {found}, expected {shape[1]} x {shape[0]}")
    with tempfile.TemporaryDirectory(prefix="terratheme-codec-") as folder:
        path = os.path.join(folder, "image" + ext)
        Path(path).write_bytes(bytes(data))
        inp = oiio.ImageInput.open(path)
        if inp is None:
            raise CorruptFileError(f"not a {codec} image ({error_line()})")
        try:
            spec = inp.spec()
            if shape is not None and (spec.height, spec.width) != tuple(shape):
                raise CorruptFileError(f"{codec} image is {spec.width} x {spec.height}, "
                                       f"expected {shape[1]} x {shape[0]}")
            pixels = inp.read_image("uint8")
        finally:
            inp.close()
    if pixels is None or not hasattr(pixels, "ndim"):
        raise CorruptFileError(f"damaged {codec} image ({error_line()})")
    return np.ascontiguousarray(pixels if pixels.ndim == 3 else pixels[:, :, None])
