"""Orthophoto to thematic texture: classify, themes, labels to a vertex grid, the cell size.

Modules: ``labels_to_grid`` (the vertex vote), ``specks`` (lone vertices
removed), ``cell_choice`` (the cell size chosen from a target), ``photo``
(the whole-image pipeline and its outputs), ``tiled`` (photos larger than
memory, tile by tile, here or on a dask.distributed cluster), ``tile_vote``
(its picklable tile jobs), ``colour_fit`` (the colour map, whole or tile by
tile).
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
