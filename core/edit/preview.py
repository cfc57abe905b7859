"""The editor's live preview: a full render kept up to date by re-rendering dirty cells.

After an edit only the cells whose render can change are re-rendered
(``render_cells(region=...)``, exactly the full render's crop) and pasted in, so the
preview equals a fresh full render at a cost that follows the edit.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from terratheme.core.edit.events import GridChange
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.project import project_style
from terratheme.core.render.renderer import render_cells

Progress = Callable[[int, int], None]
#: most texels the live preview holds (16384 x 16384: 768 MiB of RGB, the editor's
#: benchmark size); a larger texture is refused before any of it is rendered
MAX_PREVIEW_TEXELS = 1 << 28


def dirty_cells(change: GridChange, cells_shape: tuple[int, int], margin: int = 1
                ) -> tuple[slice, slice]:
    """Cells a vertex change can alter: the touched cells plus ``margin`` cells (the saddle
    rule looks at neighbours, design.md §1).
    """
    gh, gw = cells_shape
    rows = slice(max(change.rows.start - 1 - margin, 0), min(change.rows.stop + margin, gh))
    cols = slice(max(change.cols.start - 1 - margin, 0), min(change.cols.stop + margin, gw))
    return rows, cols


def dirty_region(change: GridChange, cells_shape: tuple[int, int], cell: tuple[int, int],
                 margin: int = 1) -> tuple[int, int, int, int]:
    """The dirty texel region ``(x, y, w, h)`` to re-render after ``change``."""
    rows, cols = dirty_cells(change, cells_shape, margin)
    n, m = cell
    return (cols.start * n, rows.start * m, max(cols.stop - cols.start, 0) * n,
            max(rows.stop - rows.start, 0) * m)


class RenderPreview:
    """A (H, W, 3) uint8 render of a texture's live grid and library, refreshed region by
    region (:meth:`refresh`); ``margin`` extra cells around touched ones, ``progress`` for
    the first render. TerrathemeError past ``MAX_PREVIEW_TEXELS``.
    """
    def __init__(self, texture: ThematicTexture, *, margin: int = 1,
                 progress: Progress | None = None) -> None:
        w, h = texture.grid.texture_size
        if w * h > MAX_PREVIEW_TEXELS:
            raise TerrathemeError(
                f"the editor's live preview holds the whole render: {w} x {h} texels is over "
                f"its limit of {MAX_PREVIEW_TEXELS:,} (16384 x 16384); a smaller cell or "
                "terratheme render --tiled shows it")
        self.texture = texture
        self.margin = margin
        self.image = self._render(None, progress)

    def _render(self, region: tuple[int, int, int, int] | None,
                progress: Progress | None = None) -> np.ndarray:
        # The project's own style and colour map, as terratheme render shows it.
        grid = self.texture.grid
        return render_cells(grid.indices, self.texture.library.textures, grid.cell, region,
                            progress=progress, options=project_style(self.texture),
                            colour_map=self.texture.colour_map)

    def refresh(self, change: GridChange) -> tuple[int, int, int, int] | None:
        """Re-render the cells ``change`` can affect; returns the (x, y, w, h) replaced, or None."""
        grid = self.texture.grid
        x, y, w, h = dirty_region(change, grid.cells_shape, grid.cell, self.margin)
        if w <= 0 or h <= 0:
            return None
        self.image[y : y + h, x : x + w] = self._render((x, y, w, h))
        return x, y, w, h

    def refresh_region(self, region: tuple[int, int, int, int] | None) -> None:
        """Re-render texels ``(x, y, w, h)`` (all when None) in place (the colour map changed)."""
        if region is None:
            self.refresh_all()
            return
        x, y, w, h = region
        if w > 0 and h > 0:
            self.image[y : y + h, x : x + w] = self._render((x, y, w, h))

    def refresh_all(self, progress: Progress | None = None) -> None:
        """Re-render everything in place (a theme's texture changed)."""
        self.image[...] = self._render(None, progress)
