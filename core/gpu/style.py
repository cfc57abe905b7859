"""A project's style on the GPU: blend, shaped borders and colour map, checked and bound.

:func:`gpu_style` checks it against the shaders' exact integer ranges before any GPU
work; :class:`StyleTextures` gives the uniforms every view shares.
"""

from __future__ import annotations

from typing import NamedTuple

import moderngl
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu.options import GpuRenderOptions
from terratheme.core.gpu.programs import UNITS
from terratheme.core.gpu.textures import ThemeTextures, check_colour_map, colour_map_texture
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.render.boundary import BoundaryParams
from terratheme.core.render.renderer import BlendMode
from terratheme.core.render.theme_pack import LUT_RANGE

#: largest texel coordinate and cell area the shaders' integer arithmetic keeps exact
MAX_COORDINATE = 1 << 23
MAX_CELL_AREA = 1 << 23
#: largest noise lattice of shaped borders the shaders divide exactly (L^2 <= 2^30)
MAX_LATTICE = 1 << 15


class Style(NamedTuple):
    """What a view draws besides the grid: the blend, the borders, the colour map."""

    histogram: bool
    border: BoundaryParams | None
    colour_map: ColourMap | None


def gpu_style(options: GpuRenderOptions, cell: tuple[int, int], texture_size: tuple[int, int],
              colour_map: ColourMap | None) -> Style:
    """The checked style of a ``texture_size`` texture in cells of ``cell``.

    Raises TerrathemeError for a side or cell area beyond 2^23, a noise lattice beyond
    :data:`MAX_LATTICE`, or a colour map that misses the texture or passes its scale limit.
    """
    n, m = cell
    if max(texture_size) > MAX_COORDINATE or n * m > MAX_CELL_AREA:
        raise TerrathemeError(
            f"texture {texture_size[0]} x {texture_size[1]} with {n} x {m} cells is beyond the "
            f"GPU renderer's exact integer range (sides and cell area up to {MAX_COORDINATE})")
    check_colour_map(colour_map, texture_size)
    border = None if options.boundary is None else options.boundary.parameters(n, m)
    if border is not None and border.lattice > MAX_LATTICE:
        raise TerrathemeError(f"shaped borders with a {border.lattice}-texel noise lattice "
                              f"are beyond the GPU renderer's exact range (up to "
                              f"{MAX_LATTICE}): render it on the CPU")
    return Style(options.blend is BlendMode.HISTOGRAM, border, colour_map)


class StyleTextures:
    """The themes and colour map of one renderer, bound for a view in a style."""

    def __init__(self, ctx: moderngl.Context, themes: ThemeTextures) -> None:
        self.ctx = ctx
        self.themes = themes
        self._colours: tuple[ColourMap, moderngl.Texture] | None = None

    def bind(self, style: Style, filtered: bool, anisotropy: float, box: bool = False) -> int:
        """Bind the textures the style reads (``box``: the summed-area tables too); returns
        the inverse tables' size (``TT_LUT_SIZE``)."""
        # With box means the colours are read from the tables only: no mipmapped copy.
        self.themes.colours(filtered and not box, anisotropy).use(UNITS["tt_themes"])
        if box:
            self.themes.box_sums().use(UNITS["tt_box"])
        lut_size = 4096
        if style.histogram:
            self.themes.gaussianised(filtered, anisotropy).use(UNITS["tt_gauss"])
            lut, lut_size, _ = self.themes.inverse_lut()
            lut.use(UNITS["tt_inverse_lut"])
        if style.colour_map is not None:
            colours = self._colour_texture(style.colour_map)
            colours.anisotropy = min(float(anisotropy), float(self.ctx.max_anisotropy))
            colours.use(UNITS["tt_colour_map"])
        return lut_size

    def _colour_texture(self, colour_map: ColourMap) -> moderngl.Texture:
        """The colour map's texture, uploaded once per map (a ColourMap is immutable)."""
        if self._colours is None or self._colours[0] is not colour_map:
            if self._colours is not None:
                self._colours[1].release()
            self._colours = (colour_map, colour_map_texture(self.ctx, colour_map))
        return self._colours[1]

    def uniforms(self, style: Style, texture_size: tuple[int, int],
                 max_supersample: int) -> dict[str, object]:
        """Uniforms of every view of the texture: sizes, tables, borders, colour map scale."""
        values: dict[str, object] = {
            "tt_theme_size": self.themes.sizes,
            "tt_texture_size": (float(texture_size[0]), float(texture_size[1])),
            "tt_max_supersample": int(max_supersample), "tt_lut_range": LUT_RANGE,
        }
        if style.colour_map is not None:
            values["tt_colour_scale"] = style.colour_map.scale
        if style.border is not None:
            b = style.border
            values["tt_border"] = (b.width, b.noise, b.height, b.lattice)
            values["tt_border_seed"] = b.seed
        return values

    def release(self) -> None:
        """Free the colour map's texture (the themes belong to their owner)."""
        if self._colours is not None:
            self._colours[1].release()
            self._colours = None
