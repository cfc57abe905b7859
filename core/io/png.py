"""PNG at the level of its chunks: what OpenImageIO does not do for us.

Reads the header's size and checks every chunk's length and CRC before libpng
sees the file (libpng prints its own errors on stderr); reads a palette PNG's
table with Pillow and maps OpenImageIO's expanded colours back to indices; turns
an 8-bit grey PNG into a palette PNG (same scanline bytes: only ``IHDR``'s colour
type changes and a ``PLTE`` chunk is added). PNG spec (W3C 2003) sections 5, 11.
"""

from __future__ import annotations

import functools
import os
import struct
import zlib
from pathlib import Path

import numpy as np
from PIL import PngImagePlugin, UnidentifiedImageError
from terratheme.core.errors import CorruptFileError, TerrathemeError

SIGNATURE = b"\x89PNG\r\n\x1a\n"
_COLOUR_TYPE_GREY = 0
_COLOUR_TYPE_PALETTE = 3
#: chunks whose layout differs between grey and palette images (dropped on relabelling)
_GREY_ONLY_CHUNKS = {b"bKGD", b"sBIT", b"tRNS", b"hIST"}
#: bytes read at a time while the chunks are checked
_READ = 1 << 20


def png_chunk(kind: bytes, data: bytes) -> bytes:
    """One PNG chunk: length, ``kind``, ``data``, CRC."""
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _head(path: Path, n: int) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read(n)
    except OSError:
        return b""


def is_png(path: Path) -> bool:
    """Whether the file starts with the PNG signature (whatever its name)."""
    return _head(path, 8) == SIGNATURE


def png_header_size(path: Path) -> tuple[int, int] | None:
    """``(width, height)`` from a PNG's IHDR, or None when the file is not a PNG."""
    head = _head(path, 24)
    if len(head) < 24 or head[:8] != SIGNATURE or head[12:16] != b"IHDR":
        return None
    return struct.unpack(">II", head[16:24])


def check_png_chunks(path: str | os.PathLike) -> None:
    """Refuse a PNG with damaged chunks (CRC, past the end, no IHDR/IEND) before libpng reads it."""
    st = os.stat(path)
    _check_chunks(os.fspath(path), st.st_ino, st.st_size, st.st_mtime_ns)


@functools.lru_cache(maxsize=64)
def _check_chunks(path: str, _inode: int, size: int, _mtime_ns: int) -> None:
    """:func:`check_png_chunks` of one version of a file (a failure is not cached)."""
    with open(path, "rb") as fh:
        if fh.read(8) != SIGNATURE:
            raise CorruptFileError(f"{path}: not a PNG (no PNG signature)")
        pos, first = 8, True
        while True:
            head = fh.read(8)
            if len(head) < 8:
                raise CorruptFileError(f"{path}: truncated PNG (no IEND chunk)")
            length, kind = struct.unpack(">I4s", head)
            if pos + 12 + length > size:
                raise CorruptFileError(f"{path}: truncated PNG ({kind!r} chunk past the end)")
            if first and (kind != b"IHDR" or length != 13):
                raise CorruptFileError(f"{path}: damaged PNG (no IHDR chunk first)")
            crc, left = zlib.crc32(kind), length
            while left:
                part = fh.read(min(left, _READ))
                crc, left = zlib.crc32(part, crc), left - len(part)
            if struct.unpack(">I", fh.read(4))[0] != crc:
                raise CorruptFileError(f"{path}: damaged PNG (CRC error in a {kind!r} chunk)")
            pos, first = pos + 12 + length, False
            if kind == b"IEND":
                return


def png_palette(path: str | os.PathLike) -> np.ndarray | None:
    """A palette PNG's table: ``(K, 3)`` uint8 RGB, or ``(K, 4)`` RGBA when it has tRNS.

    None for any file that is not a palette PNG; CorruptFileError for one without
    a valid PLTE (1..256 whole RGB entries).
    """
    try:
        # The plugin's class, not Image.open: its pixel-count guard refuses large
        # images before the palette is read, and no pixel is decoded here.
        with PngImagePlugin.PngImageFile(os.fspath(path)) as im:
            if im.mode != "P":
                return None
            raw = bytes(im.palette.palette) if im.palette is not None else b""
            trns = im.info.get("transparency")
    except (UnidentifiedImageError, SyntaxError, OSError, ValueError):
        with open(path, "rb") as fh:
            head = fh.read(26)
        if (len(head) == 26 and head[:8] == SIGNATURE and head[12:16] == b"IHDR"
                and head[25] == _COLOUR_TYPE_PALETTE):
            raise CorruptFileError(f"{path}: palette PNG without a valid palette") from None
        return None
    if not raw or len(raw) % 3 or len(raw) > 3 * 256:
        raise CorruptFileError(f"{path}: palette PNG without a valid palette")
    colours = np.frombuffer(raw, np.uint8).reshape(-1, 3)
    if not isinstance(trns, bytes | int):
        return colours.copy()
    alpha = np.full(len(colours), 255, np.uint8)
    if isinstance(trns, int):  # Pillow's form for one transparent entry
        alpha[trns] = 0
    else:
        alpha[: min(len(trns), len(colours))] = np.frombuffer(trns, np.uint8)[: len(colours)]
    return np.column_stack([colours, alpha])


def palette_indices(image: np.ndarray, palette: np.ndarray, path) -> np.ndarray:
    """The ``(H, W)`` uint8 palette indices of a palette PNG OpenImageIO expanded to colours.

    ``image`` is ``(H, W, 3 or 4)`` uint8 as read, ``palette`` is :func:`png_palette`'s.
    A colour missing from the palette, or shared by entries pixels use, is refused.
    """
    channels = image.shape[2]
    if channels not in (3, 4):
        raise CorruptFileError(f"{path}: palette PNG decoded with {channels} channels")
    entries = np.full((len(palette), 4), 255, np.uint32)
    entries[:, : palette.shape[1]] = palette
    weights = np.array([1 << 24, 1 << 16, 1 << 8, 1], np.uint32)[:channels]
    keys = entries[:, :channels] @ weights
    pixels = image.astype(np.uint32).reshape(-1, channels) @ weights
    order = np.argsort(keys, kind="stable")
    where = np.minimum(np.searchsorted(keys[order], pixels), len(keys) - 1)
    if not (keys[order][where] == pixels).all():
        raise CorruptFileError(f"{path}: a pixel colour is not in the file's palette")
    used_keys, counts = np.unique(keys, return_counts=True)
    shared = used_keys[counts > 1]
    if shared.size and np.isin(pixels, shared).any():
        raise CorruptFileError(f"{path}: palette entries share a colour, so their indices "
                               "cannot be told apart; give every index its own colour")
    return order[where].astype(np.uint8).reshape(image.shape[:2])


def check_palette(path, arr: np.ndarray, palette: np.ndarray) -> np.ndarray:
    """The palette of a palette PNG to write: (K, 3) uint8 for an (H, W, 1) uint8 ``arr``."""
    colours = np.asarray(palette)
    if Path(path).suffix.lower() != ".png" or arr.shape[2] != 1 or arr.dtype != np.uint8:
        raise TerrathemeError(f"cannot write {path}: a palette needs a single-channel "
                              "8-bit PNG")
    if colours.ndim != 2 or colours.shape[1] != 3 or not 1 <= len(colours) <= 256:
        raise TerrathemeError(f"cannot write {path}: a palette is 1..256 RGB colours, "
                              f"got shape {colours.shape}")
    if int(arr.max()) >= len(colours):
        raise TerrathemeError(f"cannot write {path}: value {int(arr.max())} has no colour in "
                              f"a palette of {len(colours)}")
    return np.ascontiguousarray(colours, dtype=np.uint8)


def relabel_grey_png_as_palette(path: Path, palette: np.ndarray) -> None:
    """Make the 8-bit grey PNG at ``path`` a palette PNG with ``palette`` (K, 3) uint8, in place."""
    data = Path(path).read_bytes()
    if data[:8] != SIGNATURE or data[12:16] != b"IHDR":
        raise TerrathemeError(f"cannot write {path}: the PNG writer gave no PNG header")
    length = struct.unpack(">I", data[8:12])[0]
    ihdr = bytearray(data[16 : 16 + length])
    if length != 13 or ihdr[8] != 8 or ihdr[9] != _COLOUR_TYPE_GREY:
        raise TerrathemeError(f"cannot write {path}: a palette needs an 8-bit grey image")
    ihdr[9] = _COLOUR_TYPE_PALETTE
    out = [SIGNATURE, png_chunk(b"IHDR", bytes(ihdr)), png_chunk(b"PLTE", palette.tobytes())]
    # Copy the other chunks, leaving out those whose layout is colour-type specific.
    pos = 16 + length + 4
    while pos + 8 <= len(data):
        size, kind = struct.unpack(">I4s", data[pos : pos + 8])
        end = pos + 12 + size
        if kind not in _GREY_ONLY_CHUNKS:
            out.append(data[pos:end])
        pos = end
    Path(path).write_bytes(b"".join(out))
