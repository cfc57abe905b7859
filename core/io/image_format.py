"""OpenImageIO's side of reading and writing: its error text, which extensions it writes,
and the size of a JPEG XL or AVIF image read from its header before any decoder sees it.

OpenImageIO decodes a JPEG XL image inside ``ImageInput.open``, so
:func:`jpegxl_size` reads its size from the codestream's ``SizeHeader``
(ISO/IEC 18181-1, section D.2) for the caller to check first; :func:`avif_size`
reads an AVIF's from its ``ispe`` properties (ISO/IEC 23008-12, 6.5.3).
"""

from __future__ import annotations

import os
import struct
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
from terratheme.core.errors import TerrathemeError

#: what the message on an unknown output extension suggests
KNOWN_OUTPUTS = ".png, .tif, .exr, .jpg"
#: OpenImageIO formats of no image file: their writers leave an empty file ("term" draws
#: the image on the terminal in escape sequences), the null reader makes pixels from the name
NO_FILE_FORMATS = frozenset({"null", "term"})


def first_line(text: str) -> str:
    """The first non-blank line of ``text``, stripped ("" if none)."""
    lines = [ln.strip() for ln in text.strip().splitlines() if ln.strip()]
    return lines[0] if lines else ""


def error_line(source: object = oiio) -> str:
    """The first line of the pending OpenImageIO error of ``source`` (the module, an
    ``ImageInput`` or an ``ImageOutput``); "" if there is none."""
    try:
        text = source.geterror()
    except UnicodeDecodeError:
        return "damaged header (its error text is not UTF-8)"
    return first_line(text)


def check_writable_format(path: str | os.PathLike, *, channels: int | None = None) -> None:
    """Refuse ``path`` as an image output if no OpenImageIO writer takes its extension, or
    the one that does writes no file (:data:`NO_FILE_FORMATS`); with ``channels``, also if
    that writer refuses an image of so many channels (GIF takes no one-channel image), found
    by opening it on a 1 x 1 image in a temporary folder of its own."""
    out = oiio.ImageOutput.create(str(path))
    suffix = Path(path).suffix
    if out is None or out.format_name() in NO_FILE_FORMATS:
        error_line()  # clear the library's pending error
        what = f"no image format is written as {suffix!r}" if suffix else "has no extension"
        if out is not None:
            what = f"{suffix!r} is OpenImageIO's {out.format_name()} output, which writes no file"
        raise TerrathemeError(f"{path}: {what}; name the image {KNOWN_OUTPUTS}, ...")
    if channels is None:
        return
    try:
        with tempfile.TemporaryDirectory(prefix="terratheme-probe-") as folder:
            probe = str(Path(folder) / f"probe{suffix}")
            why = _open_error(out, probe, channels)
            # A writer that takes no RGB image either says nothing of channels (the
            # temporary folder may be full): the output's own write will tell.
            if why is None or _open_error(out, probe, 3) is not None:
                return
    except OSError:
        return
    raise TerrathemeError(f"{path}: {out.format_name()} cannot hold this {channels}-channel "
                          f"image ({why}); name the image {KNOWN_OUTPUTS}, ...")


def _open_error(out: oiio.ImageOutput, probe: str, channels: int) -> str | None:
    """None if ``out`` writes a 1 x 1 uint8 image of ``channels`` channels to ``probe``,
    else its error line."""
    if not out.open(probe, oiio.ImageSpec(1, 1, channels, "uint8")):
        return error_line(out)
    out.write_image(np.zeros((1, 1, channels), np.uint8))  # no writer complains of no pixels
    out.close()
    return None


#: the bare JPEG XL codestream's signature, and the ISO BMFF container's first box
JXL_CODESTREAM = b"\xff\x0a"
JXL_CONTAINER = b"\x00\x00\x00\x0cJXL \r\n\x87\n"
#: width : height of the SizeHeader's ratio codes 1..7
_JXL_RATIOS = {1: (1, 1), 2: (12, 10), 3: (4, 3), 4: (3, 2), 5: (16, 9), 6: (5, 4), 7: (2, 1)}
_JXL_SIDE_BITS = (9, 13, 18, 30)


def is_jpegxl(head: bytes) -> bool:
    """Whether bytes start a JPEG XL file (bare codestream or container)."""
    return head.startswith(JXL_CODESTREAM) or head.startswith(JXL_CONTAINER)


def _jxl_codestream(data: bytes) -> bytes:
    """The first bytes of the codestream: ``data`` itself, or its container's jxlc box or
    jxlp boxes (a codestream in parts) joined."""
    if data.startswith(JXL_CODESTREAM):
        return data
    pos, parts = 0, b""
    while pos + 8 <= len(data) and len(parts) < 16:
        size, kind = struct.unpack_from(">I4s", data, pos)
        head = 8
        if size == 1:
            if pos + 16 > len(data):
                break
            size, head = struct.unpack_from(">Q", data, pos + 8)[0], 16
        end = len(data) if size == 0 else pos + size
        if kind == b"jxlc":
            return data[pos + head:end]
        if kind == b"jxlp":
            parts += data[pos + head + 4:end]  # after the part's 4-byte index
        if size != 0 and size < head:
            break
        pos = end
    return parts


def jpegxl_size(data: bytes) -> tuple[int, int] | None:
    """``(width, height)`` from a JPEG XL image's SizeHeader, or None if ``data`` holds none.

    ``data`` is the file's first bytes (its container boxes before the codestream and
    the codestream's first 12 bytes).
    """
    stream = _jxl_codestream(data)
    if not stream.startswith(JXL_CODESTREAM) or len(stream) < 12:
        return None
    bits = int.from_bytes(stream[2:12], "little")
    pos = 0

    def take(n: int) -> int:
        nonlocal pos
        value = (bits >> pos) & ((1 << n) - 1)
        pos += n
        return value

    def side(div8: int) -> int:
        return (take(5) + 1) * 8 if div8 else take(_JXL_SIDE_BITS[take(2)]) + 1

    div8 = take(1)
    height = side(div8)
    ratio = take(3)
    if ratio:
        num, den = _JXL_RATIOS[ratio]
        return height * num // den, height
    return side(div8), height


#: ISO BMFF boxes :func:`avif_size` descends into (``meta`` is a full box: 4 more bytes)
_AVIF_CONTAINERS = {b"meta": 4, b"iprp": 0, b"ipco": 0}


def avif_size(data: bytes) -> tuple[int, int] | None:
    """``(width, height)``, the largest of an AVIF's ``ispe`` properties; None if none.

    ``data`` is the file's first bytes (its ``ftyp`` and ``meta`` boxes).
    """
    sizes: list[tuple[int, int]] = []

    def walk(start: int, end: int, depth: int) -> None:
        pos = start
        while pos + 8 <= end and depth < 4:
            size, kind = struct.unpack_from(">I4s", data, pos)
            if size < 8:
                return
            if kind in _AVIF_CONTAINERS:
                walk(pos + 8 + _AVIF_CONTAINERS[kind], min(end, pos + size), depth + 1)
            elif kind == b"ispe" and pos + 20 <= end:
                sizes.append(struct.unpack_from(">II", data, pos + 12))
            pos += size

    if data[4:8] != b"ftyp":
        return None
    walk(0, len(data), 0)
    return max(sizes, key=lambda wh: wh[0] * wh[1]) if sizes else None


def jpegxl_file_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """:func:`jpegxl_size` of a file's first bytes (None: not JPEG XL, or unreadable)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 12)
    except OSError:
        return None
    return jpegxl_size(head) if is_jpegxl(head) else None
