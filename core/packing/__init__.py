"""Index layers packed along a space-filling curve (seed sfc_packing.txt; DESIGN.md section 2).

``pack(image)`` scans an index (or <= 256-colour) image along a Hilbert or
Morton curve into runs ``<S_i, P_i>``; the :class:`PackedLayer` reads texels
without unpacking and saves in the seed's varint layout or a compact,
entropy-coded one. :func:`layer_info` describes a file from its header alone.

Modules: :mod:`.packer` (``pack``), :mod:`.palette` (image -> palette and runs), :mod:`.layer` (the
in-memory layer), :mod:`.lookup` (random access kernels and block directory),
:mod:`.layout` (the random-access table's layout), :mod:`.container` (file
header, magic, version, checksum, ceilings), :mod:`.seed_format` (the seed's
varint pairs), :mod:`.compact_format` and :mod:`.range_coder` (entropy-coded
streams), :mod:`.info` (header-only description).

Names are loaded on first use (PEP 562), so :func:`layer_info` and the file
header readers load no numba kernel.
"""

from __future__ import annotations

__all__ = ["CurveChoice", "LayerInfo", "PackedLayer", "PaletteReport", "layer_info", "pack"]


def __getattr__(name: str) -> object:
    """Import the module that defines ``name`` when it is first asked for."""
    if name in ("LayerInfo", "layer_info"):
        from core.packing import info

        return getattr(info, name)
    if name == "PackedLayer":
        from core.packing.layer import PackedLayer

        return PackedLayer
    if name in ("CurveChoice", "pack"):
        from core.packing import packer

        return getattr(packer, name)
    if name == "PaletteReport":
        from core.packing.palette import PaletteReport

        return PaletteReport
    raise AttributeError(f"module 'core.packing' has no attribute {name!r}")
