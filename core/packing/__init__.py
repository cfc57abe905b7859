"""Index layers packed along a space-filling curve (seed sfc_packing.txt; design.md §4).

``pack(image)`` scans an index (or <= 256-colour) image along a Hilbert or
Morton curve into runs ``<S_i, P_i>``; the :class:`PackedLayer` reads texels
without unpacking and saves in the seed's varint layout or a compact,
entropy-coded one.

Modules: :mod:`.palette` (image -> palette and runs), :mod:`.layer` (the
in-memory layer), :mod:`.lookup` (random access kernels and block directory),
:mod:`.container` (file header, magic, version, checksum), :mod:`.seed_format`
(the seed's varint pairs), :mod:`.compact_format` and :mod:`.range_coder`
(entropy-coded streams).
"""

from core.packing.layer import PackedLayer
from core.packing.pack import CurveChoice, pack
from core.packing.palette import PaletteReport

__all__ = ["CurveChoice", "PackedLayer", "PaletteReport", "pack"]
