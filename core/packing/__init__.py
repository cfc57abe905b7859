"""Index layers packed along a space-filling curve (seed sfc_packing.txt; design.md §4).

``pack(image)`` scans an index (or <= 256-colour) image along a Hilbert or
Morton curve into runs ``<S_i, P_i>``; the :class:`PackedLayer` reads texels
without unpacking and saves in the seed's varint layout or a compact,
entropy-coded one. Layers over 65536 texels a side are a
:class:`TiledLayer` (a grid of packed tiles with an index, the same calls);
:func:`pack_file` packs an image file of any size band by band,
:func:`load_layer` opens either kind, :func:`layer_info` describes a file
from its header alone, and :func:`write_layer_image` unpacks to an image
file band by band (a palette PNG for index layers).

Modules: :mod:`.packer` (``pack``), :mod:`.stream_pack` (``pack_file``),
:mod:`.palette` (image -> palette and runs), :mod:`.layer` (the in-memory
layer), :mod:`.tiled` and :mod:`.tiled_format` (the tiled container),
:mod:`.lookup` (random access kernels and block directory), :mod:`.batch`
and :mod:`.sweep` (batched lookups), :mod:`.joined` (one table over a tiled
layer's tiles), :mod:`.scalar` (the quick cells of scalar lookups),
:mod:`.layout` (the random-access table's layout), :mod:`.container` (file header, magic,
version, checksum, ceilings), :mod:`.seed_format` (the seed's varint pairs),
:mod:`.compact_format` and :mod:`.range_coder` (entropy-coded run streams),
:mod:`.plane_format`, :mod:`.plane_model` and :mod:`.mixing` (the 2-D
context-mixing payload),
:mod:`.export` and :mod:`.index_png` (image files out, palette PNGs),
:mod:`.info` (header-only description).

Names are loaded on first use (PEP 562), so :func:`layer_info` and the file
header readers load no numba kernel.
"""

from __future__ import annotations

__all__ = [
    "CurveChoice",
    "LayerInfo",
    "PackedLayer",
    "PaletteReport",
    "TiledLayer",
    "layer_info",
    "load_layer",
    "pack",
    "pack_file",
    "write_layer_image",
]


def __getattr__(name: str) -> object:
    """Import the module that defines ``name`` when it is first asked for."""
    if name in ("LayerInfo", "layer_info"):
        from terratheme.core.packing import info

        return getattr(info, name)
    if name == "PackedLayer":
        from terratheme.core.packing.layer import PackedLayer

        return PackedLayer
    if name in ("CurveChoice", "pack"):
        from terratheme.core.packing import packer

        return getattr(packer, name)
    if name in ("TiledLayer", "load_layer"):
        from terratheme.core.packing import tiled

        return getattr(tiled, name)
    if name == "pack_file":
        from terratheme.core.packing.stream_pack import pack_file

        return pack_file
    if name == "write_layer_image":
        from terratheme.core.packing.export import write_layer_image

        return write_layer_image
    if name == "PaletteReport":
        from terratheme.core.packing.palette import PaletteReport

        return PaletteReport
    raise AttributeError(f"module 'terratheme.core.packing' has no attribute {name!r}")
