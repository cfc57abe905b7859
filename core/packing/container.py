"""The packed-layer file (``TTPK``): header, palette, run payload, checksum.

Byte layout, versioning rules and ceilings: docs/formats.md, P1. Every ceiling is
checked before any payload is decoded, so a small hostile file costs milliseconds;
the codecs are imported when a payload is coded, so :func:`read_header` loads no numba.
"""

from __future__ import annotations

import os
import struct
import zlib
from typing import BinaryIO, NamedTuple

import numpy as np
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError

MAGIC = b"TTPK"
#: Highest format version this build reads.
VERSION = 2
ENCODINGS = {"seed": 0, "compact": 1, "plane": 2}
#: Lowest file version that knows each encoding.
ENCODING_VERSION = {0: 1, 1: 1, 2: 2}
HEADER = struct.Struct("<4sBBBBBBHIIQQ")
FLAG_SQUEEZE = 1
FLAG_IDENTITY = 2
FLAG_COLOURS = 4
FLAG_ALPHA = 8
#: The flag bits each version knows.
VERSION_FLAGS = {1: FLAG_SQUEEZE | FLAG_IDENTITY,
                 2: FLAG_SQUEEZE | FLAG_IDENTITY | FLAG_COLOURS | FLAG_ALPHA}
#: Largest side of one layer (a curve over at most 2^32 steps).
MAX_SIDE = 65536
#: Ceiling on runs per payload byte (real maps: 1.5-3; the decoders' arrays grow with R).
MAX_RUNS_PER_BYTE = 16
#: Runs any payload may declare whatever its size (about 20 MB of decoding arrays).
RUN_ALLOWANCE = 1 << 20


class LayerFields(NamedTuple):
    """What a layer file stores (:class:`core.packing.layer.PackedLayer` is built from it).

    ``lengths`` and ``indices`` are the runs (texels per run, palette index);
    ``palette`` is ``(K, C)`` uint8 or uint16; ``colours`` the ``(K, 3|4)``
    uint8 display colours of an identity palette, or None.
    """

    width: int
    height: int
    curve: int
    lengths: np.ndarray
    indices: np.ndarray
    palette: np.ndarray
    identity: bool
    squeeze: bool
    colours: np.ndarray | None = None


class ValueFormat(NamedTuple):
    """How texel values are stored: the palette and display colours after a header.

    Shared by a layer file's header (:class:`LayerHeader`) and a tiled
    container's (``core.packing.tiled_format.TiledHeader``).
    """

    squeeze: bool
    identity: bool
    colour_channels: int
    channels: int
    sample: int
    k: int

    @classmethod
    def from_flags(cls, flags: int, channels: int, sample: int, k: int) -> ValueFormat:
        """The format a header's flag bits and palette fields describe."""
        colour_channels = (4 if flags & FLAG_ALPHA else 3) if flags & FLAG_COLOURS else 0
        return cls(bool(flags & FLAG_SQUEEZE), bool(flags & FLAG_IDENTITY), colour_channels,
                   channels, sample, k)

    @classmethod
    def of(cls, palette: np.ndarray, identity: bool, squeeze: bool,
           colours: np.ndarray | None) -> ValueFormat:
        """The format of a ``(K, C)`` palette and its ``(K, 3|4)`` display colours (or None)."""
        palette = np.asarray(palette)
        return cls(bool(squeeze), bool(identity),
                   0 if colours is None else int(np.asarray(colours).shape[1]),
                   int(palette.shape[1]), int(palette.dtype.itemsize), int(palette.shape[0]))

    @property
    def flags(self) -> int:
        """The header's flag bits of this format."""
        return ((FLAG_SQUEEZE if self.squeeze else 0) | (FLAG_IDENTITY if self.identity else 0)
                | (FLAG_COLOURS if self.colour_channels else 0)
                | (FLAG_ALPHA if self.colour_channels == 4 else 0))

    @property
    def palette_bytes(self) -> int:
        """Bytes of the stored palette (0 for an identity palette)."""
        return 0 if self.identity else self.k * self.channels * self.sample

    @property
    def colour_bytes(self) -> int:
        """Bytes of the stored display colours (0 when there are none)."""
        return self.k * self.colour_channels

    @property
    def table_bytes(self) -> int:
        """Bytes of the palette and the colours together."""
        return self.palette_bytes + self.colour_bytes


class LayerHeader(NamedTuple):
    """The fixed header of a layer file, checked (:func:`read_header`)."""

    version: int
    encoding: int
    curve: int
    values: ValueFormat
    width: int
    height: int
    runs: int
    payload: int

    @property
    def payload_at(self) -> int:
        """Offset of the payload in the file."""
        return HEADER.size + self.values.table_bytes

    @property
    def file_bytes(self) -> int:
        """Length of the whole file the header describes."""
        return self.payload_at + self.payload + 4

    @property
    def encoding_name(self) -> str:
        """``"seed"``, ``"compact"`` (run streams) or ``"plane"``."""
        return {v: k for k, v in ENCODINGS.items()}[self.encoding]


def run_ceiling(payload_bytes: int) -> int:
    """Most runs a payload of this many bytes may declare."""
    return max(RUN_ALLOWANCE, MAX_RUNS_PER_BYTE * int(payload_bytes))


def encode_layer(layer: LayerFields, encoding: str) -> bytes:
    """The bytes of a layer file in ``encoding``.

    ``"compact"`` keeps the smaller of the plane payload (encoding 2) and the
    run streams (encoding 1); ``"plane"`` and ``"streams"`` ask for one of
    them (the run streams when the plane payload cannot hold the layer);
    ``"seed"`` is the seed's varint pairs.
    """
    from terratheme.core.packing import compact_format, plane_format, seed_format

    if encoding not in (*ENCODINGS, "streams"):
        raise TerrathemeError(f"unknown packed format {encoding!r}: use 'compact' or 'seed'")
    lengths = layer.lengths
    indices = layer.indices
    ceiling_ok = run_ceiling(0) >= len(lengths)
    candidates: dict[int, bytes] = {}
    if encoding in ("compact", "plane") and plane_format.can_code(indices):
        plane = plane_format.encode_plane(layer.width, layer.height, layer.curve, lengths,
                                          indices)
        if plane is not None:
            candidates[2] = plane
    if encoding in ("compact", "streams") or (encoding == "plane" and not candidates):
        candidates[1] = compact_format.encode_runs(lengths, indices, layer.palette.shape[0])
    # Keep the smallest payload within the run ceiling; the seed layout always fits it.
    fits = {e: p for e, p in candidates.items()
            if ceiling_ok or len(lengths) <= run_ceiling(len(p))}
    if fits:
        code = min(fits, key=lambda e: len(fits[e]))
        payload = fits[code]
    else:
        code, payload = 0, seed_format.encode_seed_runs(lengths, indices)
    channels = layer.palette.shape[1]
    palette = b"" if layer.identity else layer.palette.astype(
        layer.palette.dtype.newbyteorder("<")).tobytes()
    version = ENCODING_VERSION[code]
    colours = layer.colours if layer.identity else None
    if colours is not None:
        colours = np.ascontiguousarray(colours, np.uint8)
        palette += colours.tobytes()
        version = max(version, 2)
    flags = ValueFormat.of(layer.palette, layer.identity, layer.squeeze, colours).flags
    header = HEADER.pack(
        MAGIC, version, code, int(layer.curve), flags, channels,
        layer.palette.dtype.itemsize, layer.palette.shape[0], layer.width, layer.height,
        len(lengths), len(payload),
    )
    body = header + palette + payload
    return body + struct.pack("<I", zlib.crc32(body))


def read_header(data: bytes, *, name: str) -> LayerHeader:
    """Parse and check the fixed header (magic, version, field ranges, run ceiling).

    Raises CorruptFileError (not a layer file, truncated header, a field out of range);
    UnsupportedVersionError (a version newer than :data:`VERSION`).
    """
    if len(data) < 4:
        raise CorruptFileError(f"{name}: empty or truncated file ({len(data)} bytes)")
    if data[:4] != MAGIC:
        raise CorruptFileError(
            f"{name}: not a terratheme packed layer (magic {bytes(data[:4])!r}, "
            f"expected {MAGIC!r})")
    if len(data) < HEADER.size + 4:
        raise CorruptFileError(f"{name}: truncated header ({len(data)} bytes)")
    (_, version, encoding, curve, flags, channels, sample, k, width, height, runs,
     payload) = HEADER.unpack_from(data)
    if version > VERSION:
        raise UnsupportedVersionError(
            f"{name}: packed-layer format version {version}; this build reads up to {VERSION}"
        )
    if version == 0:
        raise CorruptFileError(f"{name}: format version 0 is not valid")
    checks = (
        (encoding in ENCODING_VERSION, f"unknown encoding {encoding}"),
        (ENCODING_VERSION.get(encoding, 0) <= version,
         f"encoding {encoding} in a version-{version} file"),
        (curve in (0, 1), f"unknown curve code {curve}"),
        (1 <= channels <= 4, f"{channels} channels"),
        (sample in (1, 2), f"{sample} bytes per sample"),
        (1 <= k <= 256, f"palette of {k} colours"),
        (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE, f"size {width} x {height}"),
        (1 <= runs <= width * height, f"{runs} runs for {width} x {height} texels"),
        (not flags & FLAG_IDENTITY or channels == 1, "identity palette with colour channels"),
        (not flags & ~VERSION_FLAGS.get(version, VERSION_FLAGS[VERSION]),
         f"flags {flags:#x} in a version-{version} file"),
        (not flags & FLAG_COLOURS or flags & FLAG_IDENTITY, "display colours without an "
         "identity palette"),
        (not flags & FLAG_ALPHA or flags & FLAG_COLOURS, "colour alpha without colours"),
        (encoding == 0 or runs <= run_ceiling(payload),
         f"{runs} runs in {payload} payload bytes (at most {MAX_RUNS_PER_BYTE} per byte)"),
    )
    for ok, what in checks:
        if not ok:
            raise CorruptFileError(f"{name}: bad header: {what}")
    values = ValueFormat.from_flags(flags, channels, sample, k)
    return LayerHeader(version, encoding, curve, values, width, height, runs, payload)


def _check_length(size: int, head: LayerHeader, name: str) -> None:
    expected = head.file_bytes
    if size < expected:
        raise CorruptFileError(f"{name}: truncated: {size} bytes, header says {expected}")
    if size > expected:
        raise CorruptFileError(f"{name}: {size - expected} unexpected bytes after the data")


def read_layer_file(fh: BinaryIO, *, name: str) -> bytes:
    """The bytes of an open layer file, read only once its header is checked and its
    size is the header's (a large file that is no layer is refused unread)."""
    start = fh.read(HEADER.size + 4)
    head = read_header(start, name=name)
    _check_length(os.fstat(fh.fileno()).st_size, head, name)
    return start + fh.read(head.file_bytes - len(start))


def check_file(data: bytes, *, name: str) -> LayerHeader:
    """:func:`read_header`, then the file length and the checksum."""
    head = read_header(data, name=name)
    expected = head.file_bytes
    _check_length(len(data), head, name)
    (stored,) = struct.unpack_from("<I", data, expected - 4)
    if zlib.crc32(memoryview(data)[: expected - 4]) != stored:
        raise CorruptFileError(f"{name}: checksum mismatch: the file is damaged")
    return head


def read_palette(data: bytes, values: ValueFormat, *, at: int = HEADER.size) -> np.ndarray:
    """The ``(K, C)`` palette of a checked file (the identity ``0 .. K-1`` when not stored).

    ``values`` is a layer's or a tiled container's header's; the palette starts
    at byte ``at``, right after that header (``core.packing.tiled_format.HEADER.size``
    for a container), and the display colours follow it.
    """
    dtype = np.dtype("<u1" if values.sample == 1 else "<u2")
    if values.identity:
        palette = np.arange(values.k, dtype=dtype)[:, None]
    else:
        palette = np.frombuffer(data, dtype=dtype, count=values.k * values.channels,
                                offset=at).reshape(values.k, values.channels)
    return palette.astype(dtype.newbyteorder("="))


def read_colours(data: bytes, values: ValueFormat, *,
                 at: int = HEADER.size) -> np.ndarray | None:
    """The ``(K, 3|4)`` uint8 display colours of a checked file, or None (``at`` as for
    :func:`read_palette`)."""
    if not values.colour_channels:
        return None
    flat = np.frombuffer(data, np.uint8, count=values.k * values.colour_channels,
                         offset=at + values.palette_bytes)
    return flat.reshape(values.k, values.colour_channels).copy()


def decode_layer(data: bytes, *, name: str) -> LayerFields:
    """Parse and check a layer file (any encoding)."""
    from terratheme.core.packing import compact_format, plane_format, seed_format

    head = check_file(data, name=name)
    palette = read_palette(data, head.values)
    payload = bytes(memoryview(data)[head.payload_at: head.file_bytes - 4])
    if head.encoding == ENCODINGS["seed"]:
        lengths, indices = seed_format.decode_seed_runs(payload, head.runs, name=name)
    elif head.encoding == ENCODINGS["compact"]:
        lengths, indices = compact_format.decode_runs(payload, head.runs, head.values.k,
                                                      name=name)
    else:
        lengths, indices = plane_format.decode_plane(payload, head.width, head.height,
                                                     head.curve, head.runs, name=name)
    if indices.max() >= head.values.k:
        raise CorruptFileError(f"{name}: palette index {int(indices.max())} out of range "
                               f"(palette has {head.values.k})")
    return LayerFields(head.width, head.height, head.curve, lengths, indices, palette,
                       head.values.identity, head.values.squeeze,
                       read_colours(data, head.values))
