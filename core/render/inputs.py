"""Checks shared by every renderer: the grid, the themes and the region asked for.

The full-resolution renderer (:mod:`core.render.renderer`), the overview
renderer (:mod:`core.render.overview`) and the GPU renderer take the same
inputs and refuse them with the same messages.
"""

from __future__ import annotations

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid, validate_cell, validate_indices
from terratheme.core.themes.library import Theme, validate_texture


def theme_textures(themes: object) -> list[np.ndarray]:
    """Validate a theme sequence (``(h, w, 3|4)`` uint8 arrays or :class:`Theme`) into
    ``(h, w, 3)`` uint8 arrays."""
    if themes is None or isinstance(themes, np.ndarray) and themes.ndim not in (1, 4):
        raise TerrathemeError(
            "themes must be a sequence of (h, w, 3) textures, one per index "
            f"(got {'None' if themes is None else f'an array of shape {themes.shape}'})"
        )
    try:
        items = list(themes)  # type: ignore[arg-type]
    except TypeError as exc:
        raise TerrathemeError(f"themes must be a sequence of textures, got {themes!r}") from exc
    if not items:
        raise TerrathemeError("no themes: need at least one (h, w, 3) texture")
    out = []
    for k, t in enumerate(items):
        if isinstance(t, Theme):
            out.append(t.texture)
        else:
            out.append(validate_texture(t, name=f"theme {k}"))
    return out


def prepare_grid(
    grid: object, cell: object, n_themes: int | None
) -> tuple[np.ndarray, tuple[int, int]]:
    """Validate ``grid`` (array or :class:`IndexGrid`) and ``cell`` into ``(indices, (N, M))``."""
    if isinstance(grid, IndexGrid):
        if cell is None:
            cell = grid.cell
        grid = grid.indices
    if cell is None:
        raise TerrathemeError("cell size (N, M) is required with a plain index array")
    indices = validate_indices(grid, n_themes=n_themes)
    return indices, validate_cell(cell)


def validate_region(region: object, size: tuple[int, int]) -> tuple[int, int, int, int]:
    """Check ``region = (x, y, w, h)`` against the full texture ``size = (W, H)``."""
    full_w, full_h = size
    if region is None:
        return 0, 0, full_w, full_h
    try:
        x, y, w, h = (int(v) for v in region)  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise TerrathemeError(f"region must be four integers (x, y, w, h), got {region!r}") from exc
    if w < 1 or h < 1:
        raise TerrathemeError(f"region {w} x {h} is empty")
    if x < 0 or y < 0 or x + w > full_w or y + h > full_h:
        raise TerrathemeError(
            f"region x={x} y={y} w={w} h={h} is outside the {full_w} x {full_h} texture"
        )
    return x, y, w, h
