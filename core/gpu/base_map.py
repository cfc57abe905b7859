"""The fly-over's base map: the render itself, mipmapped, for footprints of a texel or more.

A footprint spanning many cells wants the texture's true average, as engines' base maps
give beyond their splat layers (docs/gpu.md). Edits re-render only the dirty texels.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np
from terratheme.core.gpu.options import GpuRenderOptions
from terratheme.core.gpu.programs import UNITS
from terratheme.core.gpu.renderer import GpuRenderer
from terratheme.core.model.colour_map import ColourMap


class BaseMap:
    """The render reduced ``b`` times (``b`` a power of two until the map has at most
    ``largest`` texels a side), as a mipmapped, repeating RGBA8 texture.

    ``renderer`` draws it on ``ctx`` in the style of ``options`` and ``colour_map``;
    ``indices`` (gh+1, gw+1) uint8 is the live grid, read at every update.
    """

    def __init__(self, ctx: moderngl.Context, renderer: GpuRenderer, indices: np.ndarray,
                 cell: tuple[int, int], options: GpuRenderOptions,
                 colour_map: ColourMap | None, largest: int) -> None:
        self.ctx, self.renderer, self.indices, self.cell = ctx, renderer, indices, cell
        self.options, self.colour_map = options, colour_map
        gh, gw = indices.shape[0] - 1, indices.shape[1] - 1
        size = (gw * cell[0], gh * cell[1])
        #: texels of the render per base texel (a power of two)
        self.step = 1 << max(0, math.ceil(math.log2(max(size) / max(1, largest))))
        #: the base map's size in texels; it covers ``size_in_texels`` of the render
        self.size = (max(1, size[0] // self.step), max(1, size[1] // self.step))
        self.size_in_texels = (self.size[0] * self.step, self.size[1] * self.step)
        self.texture = ctx.texture(self.size, 4)
        self.texture.repeat_x = self.texture.repeat_y = True
        self.texture.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        self.update((0, 0, *self.size_in_texels))

    def update(self, region: tuple[int, int, int, int]) -> None:
        """Re-render the base texels under texel ``region`` ``(x, y, w, h)`` and its mipmaps."""
        s = self.step
        x, y, w, h = region
        # Whole base texels covering the region, inside the part the map covers.
        x0, y0 = max(0, x // s), max(0, y // s)
        x1 = min(self.size[0], -(-(x + w) // s))
        y1 = min(self.size[1], -(-(y + h) // s))
        if x1 <= x0 or y1 <= y0:
            return
        texels = (x0 * s, y0 * s, (x1 - x0) * s, (y1 - y0) * s)
        image = self.renderer.render(self.indices, self.cell, texels, scale=1.0 / s,
                                     options=self.options, colour_map=self.colour_map)
        rgba = np.empty(image.shape[:2] + (4,), np.uint8)
        rgba[..., :3], rgba[..., 3] = image, 255
        self.texture.write(rgba.tobytes(), viewport=(x0, y0, x1 - x0, y1 - y0))
        self.texture.build_mipmaps()

    def bind(self, anisotropy: float) -> None:
        """Bind to ``tt_base`` with the sampler's anisotropy."""
        self.texture.anisotropy = min(float(anisotropy), float(self.ctx.max_anisotropy))
        self.texture.use(UNITS["tt_base"])

    def uniforms(self) -> dict[str, object]:
        """``tt_base_step`` and ``tt_base_span`` of ``tt_ground.frag.glsl``."""
        return {"tt_base_step": float(self.step),
                "tt_base_span": (float(self.size_in_texels[0]), float(self.size_in_texels[1]))}

    def release(self) -> None:
        self.texture.release()
