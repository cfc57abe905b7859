"""Orthophoto to thematic texture: classify, themes, labels to a vertex grid, the cell size.

``step`` (the one conversion step), ``photo`` (whole image and outputs), ``tiled``,
``tile_vote`` and ``region_sample`` (photos larger than memory), ``labels_to_grid``,
``specks``, ``cell_choice``, ``colour_fit`` (the colour map).
"""

from terratheme.core.convert.cell_choice import CellChoice, choose_cell_size
from terratheme.core.convert.labels_to_grid import labels_to_grid, vote_grid
from terratheme.core.convert.photo import (
    ConvertOptions,
    ConvertResult,
    convert_photo,
    write_outputs,
)
from terratheme.core.convert.specks import remove_specks
from terratheme.core.convert.tiled import convert_file_tiled

__all__ = [
    "CellChoice",
    "ConvertOptions",
    "ConvertResult",
    "choose_cell_size",
    "convert_file_tiled",
    "convert_photo",
    "labels_to_grid",
    "remove_specks",
    "vote_grid",
    "write_outputs",
]
