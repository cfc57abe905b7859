"""Which blend an export's weights follow: the project's own style or the paper's rule.

``WeightStyle.PROJECT`` (default) follows the project's shaped borders when it has
them, so an engine shows what ``terratheme render`` shows; otherwise, and with
``WeightStyle.LINEAR``, the paper's barycentric weights.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from terratheme.core.exchange.options import ExportOptions, WeightStyle
from terratheme.core.exchange.shaped import shaped_slots
from terratheme.core.exchange.weights import (
    BAND_PIXELS,
    CornerSlots,
    check_window,
    quantised_bands,
    sample_corners,
    strongest_two,
)
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.project import project_style
from terratheme.core.render.renderer import RenderOptions
from terratheme.core.render.rules import cell_splits


def export_boundary(project: ThematicTexture, options: ExportOptions) -> BoundaryOptions | None:
    """The border style an export follows: the project's shaped borders, or None (linear)."""
    if options.style is WeightStyle.LINEAR:
        return None
    return project_style(project).boundary


def export_render_options(project: ThematicTexture, options: ExportOptions) -> RenderOptions:
    """The render options of a baked export texture: the export's style and saddle rule."""
    if options.style is WeightStyle.LINEAR:
        return RenderOptions(saddle=options.saddle)
    return dataclasses.replace(project_style(project), saddle=options.saddle)


def map_slots(project: ThematicTexture, size: tuple[int, int],
              window: tuple[int, int, int, int] | None, options: ExportOptions, *,
              splits: np.ndarray | None = None) -> CornerSlots:
    """Every pixel's themes and exact weights (barycentric or shaped) in a window of a
    ``size = (W, H)`` map."""
    grid = project.grid.indices
    if splits is None:
        splits = cell_splits(grid, options.saddle)
    boundary = export_boundary(project, options)
    if boundary is None:
        return sample_corners(grid, size, window, splits=splits)
    return shaped_slots(grid, project.library.textures, project.grid.cell, size, window,
                        boundary=boundary, splits=splits)


def map_weights(project: ThematicTexture, size: tuple[int, int],
                window: tuple[int, int, int, int] | None, options: ExportOptions, *,
                total: int = 255) -> np.ndarray:
    """Weights (K, h, w) of a window of a ``size = (W, H)`` map, summing to ``total`` per pixel
    (uint8, or uint16 above 255)."""
    splits = cell_splits(project.grid.indices, options.saddle)
    return quantised_bands(lambda band: map_slots(project, size, band, options, splits=splits),
                           len(project.library), size, window, total=total)


def map_labels(project: ThematicTexture, size: tuple[int, int],
               window: tuple[int, int, int, int] | None, options: ExportOptions) -> np.ndarray:
    """(h, w) uint8: the theme of largest exact weight at every pixel (ties: the lower theme)."""
    x, y, w, h = check_window(window, size)
    splits = cell_splits(project.grid.indices, options.saddle)
    out = np.empty((h, w), np.uint8)
    rows = max(1, BAND_PIXELS // w)
    # Row bands bound the (4, rows, w) slots.
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        slots = map_slots(project, size, (x, y + r0, w, r1 - r0), options, splits=splits)
        out[r0:r1] = strongest_two(slots)[0]
    return out
