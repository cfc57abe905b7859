"""PNG at the level of its chunks: what OpenImageIO does not do for us.

A PNG is an 8-byte signature and a list of chunks (4-byte big-endian length,
4-byte type, data, CRC-32 of type + data), ``IHDR`` first (PNG spec, W3C
2003, sections 5 and 11). OpenImageIO reads and writes the pixels; this
module only

* reads the header's size (:func:`png_header_size`) so a 0 x 0 PNG is
  refused before libpng sees it;
* reads a palette PNG's ``PLTE``/``tRNS`` (:func:`palette_of_png`) and maps
  the colours OpenImageIO expanded it to back to indices
  (:func:`palette_indices`): OpenImageIO gives no access to them;
* turns an 8-bit grey PNG that OpenImageIO wrote into a palette PNG
  (:func:`relabel_grey_png_as_palette`): the scanline bytes of 8-bit grey
  and 8-bit palette images are identical, so only ``IHDR``'s colour type
  changes and a ``PLTE`` chunk is added (OpenImageIO writes no palettes);
* keeps libpng's own ``libpng error: ...`` lines off the terminal
  (:func:`libpng_quiet`): libpng prints them on file descriptor 2 before
  OpenImageIO turns the failure into an error message of its own.
"""

from __future__ import annotations

import contextlib
import os
import struct
import sys
import tempfile
import threading
import zlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from terratheme.core.errors import CorruptFileError, TerrathemeError

SIGNATURE = b"\x89PNG\r\n\x1a\n"
_COLOUR_TYPE_GREY = 0
_COLOUR_TYPE_PALETTE = 3
#: chunks whose layout differs between grey and palette images (dropped on relabelling)
_GREY_ONLY_CHUNKS = {b"bKGD", b"sBIT", b"tRNS", b"hIST"}
#: most chunks read while looking for the palette (a genuine file has a handful before IDAT)
_MAX_HEADER_CHUNKS = 4096


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _chunks_before_data(fh) -> Iterator[tuple[bytes, bytes]]:
    """(type, data) of the chunks before the first IDAT; stops at a damaged one."""
    for _ in range(_MAX_HEADER_CHUNKS):
        head = fh.read(8)
        if len(head) < 8:
            return
        length, kind = struct.unpack(">I4s", head)
        if kind == b"IDAT" or length > 1 << 20:
            return
        data = fh.read(length)
        crc = fh.read(4)
        if len(data) < length or len(crc) < 4:
            return
        yield kind, data


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


def palette_of_png(path: Path) -> np.ndarray | None:
    """A palette PNG's colours as ``(K, 4)`` uint8 RGBA (alpha from tRNS, else 255).

    Returns None when the file is not a palette PNG.
    """
    try:
        with open(path, "rb") as fh:
            if fh.read(8) != SIGNATURE:
                return None
            chunks = dict(_chunks_before_data(fh))
    except OSError:
        return None
    ihdr = chunks.get(b"IHDR", b"")
    if len(ihdr) != 13 or ihdr[9] != _COLOUR_TYPE_PALETTE:
        return None
    plte = chunks.get(b"PLTE", b"")
    if not plte or len(plte) % 3 or len(plte) > 3 * 256:
        raise CorruptFileError(f"{path}: palette PNG without a valid palette")
    colours = np.frombuffer(plte, np.uint8).reshape(-1, 3)
    alpha = np.full(len(colours), 255, np.uint8)
    trns = np.frombuffer(chunks.get(b"tRNS", b"")[: len(colours)], np.uint8)
    alpha[: len(trns)] = trns
    return np.column_stack([colours, alpha])


def palette_indices(image: np.ndarray, palette: np.ndarray, path) -> np.ndarray:
    """The palette indices of a palette PNG that OpenImageIO expanded to colours.

    Parameters
    ----------
    image : (H, W, 3 or 4) uint8 ndarray
        The pixels as read (RGB, or RGBA when the file has tRNS).
    palette : (K, 4) uint8 ndarray
        :func:`palette_of_png`.
    path : path-like
        For messages.

    Returns
    -------
    indices : (H, W) uint8 ndarray

    Raises
    ------
    TerrathemeError
        Entries of the palette that pixels use share a colour (ambiguous).
    """
    channels = image.shape[2]
    entries = palette[:, :channels].astype(np.uint32)
    weights = np.array([1 << 24, 1 << 16, 1 << 8, 1][-channels:], np.uint32)
    keys = entries @ weights
    pixels = image.astype(np.uint32).reshape(-1, channels) @ weights
    order = np.argsort(keys, kind="stable")
    where = np.searchsorted(keys[order], pixels)
    where = np.minimum(where, len(keys) - 1)
    found = keys[order][where] == pixels
    if not found.all():
        raise CorruptFileError(f"{path}: a pixel colour is not in the file's palette")
    index = order[where]
    used_keys, counts = np.unique(keys, return_counts=True)
    shared = set(used_keys[counts > 1].tolist())
    if shared and np.isin(pixels, list(shared)).any():
        raise TerrathemeError(f"{path}: palette entries share a colour, so their class "
                              "numbers cannot be told apart; save the labels as grey")
    return index.astype(np.uint8).reshape(image.shape[:2])


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
    out = [SIGNATURE, _chunk(b"IHDR", bytes(ihdr)), _chunk(b"PLTE", palette.tobytes())]
    # Copy the other chunks, leaving out those whose layout is colour-type specific.
    pos = 16 + length + 4
    while pos + 8 <= len(data):
        size, kind = struct.unpack(">I4s", data[pos : pos + 8])
        end = pos + 12 + size
        if kind not in _GREY_ONLY_CHUNKS:
            out.append(data[pos:end])
        pos = end
    Path(path).write_bytes(b"".join(out))


_quiet_lock = threading.Lock()
_quiet_state = {"depth": 0, "saved": -1, "capture": None}


def _restore_stderr() -> None:
    capture = _quiet_state["capture"]
    os.dup2(_quiet_state["saved"], 2)
    os.close(_quiet_state["saved"])
    capture.seek(0)
    text = capture.read()
    capture.close()
    # Replay what others wrote meanwhile; drop libpng's own lines.
    kept = b"".join(line for line in text.splitlines(keepends=True)
                    if not line.startswith((b"libpng error", b"libpng warning")))
    if kept:
        os.write(2, kept)


@contextlib.contextmanager
def libpng_quiet(active: bool = True) -> Iterator[None]:
    """Send file descriptor 2 to a temporary file meanwhile; replay all but libpng's lines.

    Nested and concurrent uses share one redirection (the last to leave
    restores it). ``active=False`` does nothing (not a PNG).
    """
    if not active:
        yield
        return
    with _quiet_lock:
        if _quiet_state["depth"] == 0:
            with contextlib.suppress(ValueError, OSError):
                sys.stderr.flush()
            capture = tempfile.TemporaryFile()
            _quiet_state["saved"] = os.dup(2)
            _quiet_state["capture"] = capture
            os.dup2(capture.fileno(), 2)
        _quiet_state["depth"] += 1
    try:
        yield
    finally:
        with _quiet_lock:
            _quiet_state["depth"] -= 1
            if _quiet_state["depth"] == 0:
                with contextlib.suppress(ValueError, OSError):
                    sys.stderr.flush()
                _restore_stderr()
