"""Index layers packed along a space-filling curve (seed sfc_packing.txt; design.md §4).

``pack(image)`` scans an index (or <= 256-colour) image into runs ``<S_i, P_i>``; a
:class:`PackedLayer` reads texels without unpacking and saves in the formats of
docs/formats.md; layers over 65536 texels a side are a :class:`TiledLayer`.
Names are loaded on first use (PEP 562), so header readers load no numba kernel.
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
