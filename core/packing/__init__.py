"""Index layers packed along a space-filling curve (seed sfc_packing.txt; design.md §4).

``pack(image)`` scans an index (or <= 256-colour) image into runs ``<S_i, P_i>``; a
:class:`PackedLayer` reads texels without unpacking and saves in the formats of
docs/formats.md; layers over 65536 texels a side are a :class:`TiledLayer`.
Names are loaded on first use (PEP 562), so header readers load no numba kernel.
"""

from __future__ import annotations

from importlib import import_module

#: each public name and the module of this package that defines it
_HOME = {
    "CurveChoice": "packer",
    "LayerInfo": "info",
    "PackedLayer": "layer",
    "PaletteReport": "palette",
    "TiledLayer": "tiled",
    "layer_info": "info",
    "load_layer": "tiled",
    "pack": "packer",
    "pack_file": "stream_pack",
    "write_layer_image": "export",
}

__all__ = sorted(_HOME)


def __getattr__(name: str) -> object:
    """Import the module that defines ``name`` when it is first asked for."""
    if name not in _HOME:
        raise AttributeError(f"module 'terratheme.core.packing' has no attribute {name!r}")
    return getattr(import_module(f"terratheme.core.packing.{_HOME[name]}"), name)
