"""The index grid: theme numbers at grid vertices (Vyatkin & Romanyuk, design.md §1).

A grid of ``(gh+1, gw+1)`` vertex indices with a cell of ``N x M`` texels (N columns,
M rows) renders to a ``gw*N x gh*M`` texture; compression grows with ``N*M``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from terratheme.core.errors import TerrathemeError

MAX_THEMES = 256
#: largest cell side in texels: 16 repeats of a 256-texel theme, so a region render's
#: buffers stay a few tens of MiB per cell
MAX_CELL = 4096


def validate_indices(indices: object, *, n_themes: int | None = None) -> np.ndarray:
    """``indices`` ((gh+1, gw+1) whole numbers) as a C-contiguous uint8 array.

    Raises TerrathemeError if not 2-D, under 2 x 2 vertices, not whole numbers, or out of
    0..255 (or of ``0..n_themes-1`` when given).
    """
    arr = np.asarray(indices)
    if arr.ndim != 2:
        raise TerrathemeError(f"index grid must be 2-D (rows, columns), got shape {arr.shape}")
    if arr.shape[0] < 2 or arr.shape[1] < 2:
        raise TerrathemeError(
            "index grid needs at least 2 x 2 vertices (one cell), "
            f"got {arr.shape[1]} x {arr.shape[0]}"
        )
    whole_floats = (arr.dtype.kind == "f" and np.all(np.isfinite(arr))
                    and np.all(arr == np.round(arr)))
    if arr.dtype.kind not in "iub" and not whole_floats:
        raise TerrathemeError(f"index grid must hold integers, got dtype {arr.dtype}")
    # Range checks on the values as they are (a cast of 1e30 to int64 would wrap).
    if arr.size and int(arr.min()) < 0:
        raise TerrathemeError(f"index grid has a negative index ({int(arr.min())})")
    if arr.size and int(arr.max()) >= MAX_THEMES:
        raise TerrathemeError(f"index grid has index {int(arr.max())}; at most {MAX_THEMES} themes")
    if n_themes is not None and arr.size and int(arr.max()) >= n_themes:
        bad = int(arr.max())
        raise TerrathemeError(
            f"index grid uses theme index {bad} but the library has only {n_themes} themes "
            f"(0..{n_themes - 1})"
        )
    return np.ascontiguousarray(arr, dtype=np.uint8)


def validate_cell(cell: object) -> tuple[int, int]:
    """A cell size ``(N, M)`` (texel columns, rows) as two ints; TerrathemeError unless both
    are whole numbers (not bools) in 1..:data:`MAX_CELL`."""
    if isinstance(cell, str | bytes) or not hasattr(cell, "__len__") or len(cell) != 2:
        raise TerrathemeError(f"cell size must be two whole numbers (N, M), got {cell!r}")
    n, m = cell  # type: ignore[misc]
    if not all(isinstance(v, int | np.integer) and not isinstance(v, bool | np.bool_)
               for v in (n, m)):
        raise TerrathemeError(f"cell size must be two whole numbers (N, M), got {cell!r}")
    n, m = int(n), int(m)
    if n < 1 or m < 1:
        raise TerrathemeError(f"cell size must be at least 1 x 1 texels, got {n} x {m}")
    if n > MAX_CELL or m > MAX_CELL:
        raise TerrathemeError(f"cell size {n} x {m} is over the limit of {MAX_CELL} texels "
                              "per side")
    return n, m


@dataclass(eq=False)
class IndexGrid:
    """Theme indices at grid vertices plus the cell size in texels.

    ``indices`` ``(gh+1, gw+1) uint8``: ``indices[j, i]`` is the theme at vertex
    column ``i``, row ``j`` (row 0 at the top), mutable in place (the editor paints
    into it). ``cell`` ``(N, M)``: texel columns and rows of one cell.
    """

    indices: np.ndarray
    cell: tuple[int, int] = (16, 16)

    def __post_init__(self) -> None:
        self.indices = validate_indices(self.indices)
        self.cell = validate_cell(self.cell)

    @property
    def cells_shape(self) -> tuple[int, int]:
        """``(gh, gw)``: cell rows and columns."""
        return self.indices.shape[0] - 1, self.indices.shape[1] - 1

    @property
    def texture_size(self) -> tuple[int, int]:
        """``(width, height)`` in texels of the full-resolution render."""
        gh, gw = self.cells_shape
        return gw * self.cell[0], gh * self.cell[1]

    def copy(self) -> IndexGrid:
        return IndexGrid(self.indices.copy(), self.cell)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, IndexGrid):
            return NotImplemented
        return self.cell == other.cell and np.array_equal(self.indices, other.indices)
