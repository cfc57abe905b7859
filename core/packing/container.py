"""The packed-layer file: header, palette, run payload, checksum.

Layout (little-endian), the seed's Tables 1-2 plus a magic number, a version
and a checksum::

    offset size  field
    0      4     magic b"TTPK"
    4      1     format version (1)
    5      1     encoding: 0 = seed (varint pairs), 1 = compact (entropy coded)
    6      1     curve: 0 = Hilbert, 1 = Morton
    7      1     flags: bit 0 = 2-D image, bit 1 = identity palette (P = pixel value)
    8      1     channels C (1..4)
    9      1     bytes per sample (1 or 2)
    10     2     palette entries K (1..256)
    12     4     width  (1..65536)
    16     4     height (1..65536)
    20     8     run count R
    28     8     payload bytes
    36     ...   palette, K*C samples (absent for an identity palette)
    ...    ...   payload (core.packing.seed_format or core.packing.compact_format)
    end-4  4     CRC-32 of every byte before it
"""

from __future__ import annotations

import struct
import zlib
from typing import NamedTuple

import numpy as np

from core.curves.steps import MAX_SIDE, Curve
from core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from core.packing import compact_format, seed_format

MAGIC = b"TTPK"
VERSION = 1
ENCODINGS = {"seed": 0, "compact": 1}
_HEADER = struct.Struct("<4sBBBBBBHIIQQ")
FLAG_SQUEEZE = 1
FLAG_IDENTITY = 2


class LayerFields(NamedTuple):
    """What a layer file stores (:class:`core.packing.layer.PackedLayer` is built from it).

    ``lengths`` and ``indices`` are the runs (texels per run, palette index);
    ``palette`` is ``(K, C)`` uint8 or uint16.
    """

    width: int
    height: int
    curve: Curve
    lengths: np.ndarray
    indices: np.ndarray
    palette: np.ndarray
    identity: bool
    squeeze: bool


def encode_layer(layer: LayerFields, encoding: str) -> bytes:
    """The bytes of a layer file in ``encoding`` (``"seed"`` or ``"compact"``)."""
    if encoding not in ENCODINGS:
        raise TerrathemeError(f"unknown packed format {encoding!r}: use 'compact' or 'seed'")
    lengths = layer.lengths
    indices = layer.indices
    channels = layer.palette.shape[1]
    if encoding == "seed":
        payload = seed_format.encode_seed_runs(lengths, indices)
    else:
        payload = compact_format.encode_runs(lengths, indices, layer.palette.shape[0])
    palette = b"" if layer.identity else layer.palette.astype(
        layer.palette.dtype.newbyteorder("<")).tobytes()
    flags = (FLAG_SQUEEZE if layer.squeeze else 0) | (FLAG_IDENTITY if layer.identity else 0)
    header = _HEADER.pack(
        MAGIC, VERSION, ENCODINGS[encoding], int(layer.curve), flags, channels,
        layer.palette.dtype.itemsize, layer.palette.shape[0], layer.width, layer.height,
        len(lengths), len(payload),
    )
    body = header + palette + payload
    return body + struct.pack("<I", zlib.crc32(body))


def read_header(data: bytes, *, name: str) -> dict:
    """Parse and check the fixed header (magic, version, field ranges)."""
    if len(data) < 4:
        raise CorruptFileError(f"{name}: empty or truncated file ({len(data)} bytes)")
    if data[:4] != MAGIC:
        raise CorruptFileError(
            f"{name}: not a terratheme packed layer (magic {data[:4]!r}, expected {MAGIC!r})"
        )
    if len(data) < _HEADER.size + 4:
        raise CorruptFileError(f"{name}: truncated header ({len(data)} bytes)")
    (_, version, encoding, curve, flags, channels, sample, k, width, height, runs,
     payload) = _HEADER.unpack_from(data)
    if version > VERSION:
        raise UnsupportedVersionError(
            f"{name}: packed-layer format version {version}; this build reads up to {VERSION}"
        )
    if version == 0:
        raise CorruptFileError(f"{name}: format version 0 is not valid")
    checks = (
        (encoding in ENCODINGS.values(), f"unknown encoding {encoding}"),
        (curve in (0, 1), f"unknown curve code {curve}"),
        (1 <= channels <= 4, f"{channels} channels"),
        (sample in (1, 2), f"{sample} bytes per sample"),
        (1 <= k <= 256, f"palette of {k} colours"),
        (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE, f"size {width} x {height}"),
        (1 <= runs <= width * height, f"{runs} runs for {width} x {height} texels"),
        (not flags & FLAG_IDENTITY or channels == 1, "identity palette with colour channels"),
    )
    for ok, what in checks:
        if not ok:
            raise CorruptFileError(f"{name}: bad header: {what}")
    return dict(encoding=encoding, curve=Curve(curve), flags=flags, channels=channels,
                sample=sample, k=k, width=width, height=height, runs=runs, payload=payload)


def decode_layer(data: bytes, *, name: str) -> LayerFields:
    """Parse and check a layer file (either encoding)."""
    head = read_header(data, name=name)
    identity = bool(head["flags"] & FLAG_IDENTITY)
    pal_bytes = 0 if identity else head["k"] * head["channels"] * head["sample"]
    expected = _HEADER.size + pal_bytes + head["payload"] + 4
    if len(data) < expected:
        raise CorruptFileError(f"{name}: truncated: {len(data)} bytes, header says {expected}")
    if len(data) > expected:
        raise CorruptFileError(f"{name}: {len(data) - expected} unexpected bytes after the data")
    (stored,) = struct.unpack_from("<I", data, expected - 4)
    if zlib.crc32(memoryview(data)[: expected - 4]) != stored:
        raise CorruptFileError(f"{name}: checksum mismatch: the file is damaged")
    dtype = np.dtype("<u1" if head["sample"] == 1 else "<u2")
    start = _HEADER.size
    if identity:
        palette = np.arange(head["k"], dtype=dtype)[:, None]
    else:
        palette = np.frombuffer(data, dtype=dtype, count=head["k"] * head["channels"],
                                offset=start).reshape(head["k"], head["channels"])
    payload = bytes(memoryview(data)[start + pal_bytes: expected - 4])
    if head["encoding"] == ENCODINGS["seed"]:
        lengths, indices = seed_format.decode_seed_runs(payload, head["runs"], name=name)
    else:
        lengths, indices = compact_format.decode_runs(payload, head["runs"], head["k"], name=name)
    if indices.max() >= head["k"]:
        raise CorruptFileError(
            f"{name}: palette index {int(indices.max())} out of range (palette has {head['k']})"
        )
    return LayerFields(head["width"], head["height"], head["curve"], lengths, indices,
                       palette.astype(dtype.newbyteorder("=")), identity,
                       bool(head["flags"] & FLAG_SQUEEZE))
