"""What a packed-layer file holds, from its header alone (``terratheme info``).

Reads the header, the palette and the checksum; decodes no payload and loads
no numba kernel, so it answers in milliseconds whatever the layer's size.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from core.curves.square import Curve, curve_order
from core.errors import TerrathemeError
from core.packing.container import check_file, read_palette
from core.packing.layout import table_words


@dataclass(frozen=True)
class LayerInfo:
    """A packed layer's description.

    Attributes
    ----------
    width, height : int
    curve : str
        ``"hilbert"`` or ``"morton"``.
    channels : int
    identity_palette : bool
        Single-channel layer whose palette index is the texel value.
    palette : list of lists of int
        ``K`` colours of ``channels`` samples.
    run_count : int
    file_bytes : int
    memory_bytes : int
        Bytes of the in-memory random-access table once loaded.
    format : str
        Payload encoding: ``"seed"`` or ``"compact"``.
    version : int
        File format version.
    """

    width: int
    height: int
    curve: str
    channels: int
    identity_palette: bool
    palette: list
    run_count: int
    file_bytes: int
    memory_bytes: int
    format: str
    version: int


def layer_info(path: str | os.PathLike) -> LayerInfo:
    """Describe a packed-layer file without decoding its runs.

    Raises
    ------
    TerrathemeError
        Missing file; :class:`CorruptFileError` for a damaged or foreign file.
    """
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise TerrathemeError(f"{p}: no such file")
    with open(p, "rb") as fh:
        data = fh.read()
    head = check_file(data, name=p)
    n = curve_order(head.width, head.height)
    return LayerInfo(
        width=head.width, height=head.height, curve=Curve(head.curve).name.lower(),
        channels=head.channels, identity_palette=head.identity,
        palette=read_palette(data, head).tolist(), run_count=head.runs,
        file_bytes=len(data), memory_bytes=4 * table_words(n, head.runs),
        format=head.encoding_name, version=head.version,
    )
