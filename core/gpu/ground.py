"""The thematic texture on a ground plane seen in perspective, drawn by the GPU (the fly-over).

The renderer's filtered path and the project's style on the plane of eq. 1 (the CPU
preview's mapping, repeating to the horizon), or on a mesh displaced by a height map.
Edits re-split only the cells around them (docs/gpu.md, "The fly-over").
"""

from __future__ import annotations

from collections.abc import Sequence

import moderngl
import numpy as np
from terratheme.core.edit.events import GridChange
from terratheme.core.edit.preview import dirty_cells
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu.base_map import BaseMap
from terratheme.core.gpu.context import gl_context
from terratheme.core.gpu.ground_mesh import HeightField
from terratheme.core.gpu.options import (
    SOFTWARE_RENDERERS,
    Anisotropy,
    GpuRenderOptions,
    GroundOptions,
)
from terratheme.core.gpu.pipeline import Pipeline
from terratheme.core.gpu.programs import UNITS, Variant
from terratheme.core.gpu.renderer import GpuRenderer
from terratheme.core.gpu.style import StyleTextures, gpu_style
from terratheme.core.gpu.textures import ThemeTextures
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.project import ThematicTexture
from terratheme.core.perspective import Camera, PlaneMapping, check_size, view_mapping
from terratheme.core.perspective.flight import clip_matrix
from terratheme.core.render.inputs import prepare_grid, theme_textures
from terratheme.core.render.project import project_style
from terratheme.core.render.renderer import RenderOptions
from terratheme.core.render.rules import region_splits
from terratheme.core.themes.library import Theme


class GroundView:
    """A grid, its themes and its style on the GPU, drawn on the ground plane.

    ``grid`` (gh+1, gw+1) is kept by reference: edits show after :meth:`mark_dirty`.
    ``context`` must be current on this thread (default: the thread's EGL context).
    Raises TerrathemeError for bad inputs (before any GPU work) or a grid beyond the
    driver's textures, GpuUnavailableError without OpenGL 3.3.
    """

    def __init__(self, grid: object, themes: Sequence[np.ndarray] | Sequence[Theme],
                 cell: tuple[int, int] | None = None, *, style: RenderOptions = RenderOptions(),
                 colour_map: ColourMap | None = None,
                 options: GroundOptions = GroundOptions(),  # noqa: B008 (frozen)
                 context: moderngl.Context | None = None) -> None:
        textures = theme_textures(themes)
        self.indices, self.cell = prepare_grid(grid, cell, len(textures))
        gh, gw = self.indices.shape[0] - 1, self.indices.shape[1] - 1
        self.texture_size = (gw * self.cell[0], gh * self.cell[1])
        self.saddle = style.saddle
        self.gpu_options = GpuRenderOptions.from_render_options(
            style, max_anisotropy=options.max_anisotropy, max_supersample=options.max_supersample)
        self.style = gpu_style(self.gpu_options, self.cell, self.texture_size, colour_map)
        self.options = options
        self.ctx = context if context is not None else gl_context()
        limit = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        if max(self.indices.shape) > limit:
            raise TerrathemeError(f"grid of {gw + 1} x {gh + 1} vertices: this OpenGL driver's "
                                  f"textures hold at most {limit} a side")
        self.themes = ThemeTextures(self.ctx, textures)
        #: the shader's probe count (``TT_PROBES``; 0: the driver filters) and the sampler's
        self.probes = int(options.max_anisotropy) if self._shader_filters(options) else 0
        self.sampler_anisotropy = 1.0 if self.probes else float(options.max_anisotropy)
        self.textures = StyleTextures(self.ctx, self.themes)
        self.pipeline = Pipeline(self.ctx, len(textures), self.themes.one_size)
        self.heights: HeightField | None = None
        self._grid = self._index_texture(self.indices)
        self._splits = self._index_texture(region_splits(self.indices, None, self.saddle,
                                                         (0, gh - 1, 0, gw - 1)))
        self._dirty: list[tuple[slice, slice]] = []
        self.base: BaseMap | None = None
        if options.base_map:
            # The render itself for wide footprints, drawn by the flat renderer (same style).
            self._renderer = GpuRenderer(textures, context=self.ctx)
            self.base = BaseMap(self.ctx, self._renderer, self.indices, self.cell,
                                GpuRenderOptions.from_render_options(style), colour_map,
                                options.base_map)
        self._plane = self.ctx.vertex_array(self.pipeline.program(self._variant(False)), [])
        self._fbo: moderngl.Framebuffer | None = None
        self._reduced: moderngl.Framebuffer | None = None
        self._present: moderngl.VertexArray | None = None
        #: cell boxes ``(x, y, w, h)`` re-split by the last draw that had edits to upload
        self.uploaded: list[tuple[int, int, int, int]] = []

    def _shader_filters(self, options: GroundOptions) -> bool:
        """True when the shader filters anisotropically (``Anisotropy``)."""
        if options.anisotropy is Anisotropy.AUTO:
            renderer = str(self.ctx.info.get("GL_RENDERER", "")).lower()
            return options.max_anisotropy > 1 and any(s in renderer for s in SOFTWARE_RENDERERS)
        return options.anisotropy is Anisotropy.SHADER and options.max_anisotropy > 1

    @classmethod
    def from_project(cls, project: ThematicTexture,
                     options: GroundOptions = GroundOptions(),  # noqa: B008 (frozen)
                     context: moderngl.Context | None = None) -> GroundView:
        """A project in its own style (shaped borders, colour map)."""
        return cls(project.grid, project.library.textures, style=project_style(project),
                   colour_map=project.colour_map, options=options, context=context)

    def _index_texture(self, values: np.ndarray) -> moderngl.Texture:
        h, w = values.shape
        tex = self.ctx.texture((w, h), 1, np.ascontiguousarray(values, np.uint8).tobytes(),
                               dtype="u1")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return tex

    def _variant(self, mesh: bool) -> Variant:
        lut = self.themes.inverse_lut()[1] if self.style.histogram else 4096
        return Variant("ground_mesh" if mesh else "ground", histogram=self.style.histogram,
                       shaped=self.style.border is not None, filtered=True, wrap=not mesh,
                       colour_map=self.style.colour_map is not None, lut_size=lut,
                       probes=self.probes, base=self.base is not None)

    # -- edits -----------------------------------------------------------------
    def mark_dirty(self, rows: slice, cols: slice) -> None:
        """Vertices ``indices[rows, cols]`` changed: upload them at the next draw."""
        self._dirty.append((rows, cols))

    def _flush(self) -> None:
        """Upload the changed vertices and re-split the cells they (and the saddle ring) touch."""
        if not self._dirty:
            return
        self.uploaded = []
        gh, gw = self.indices.shape[0] - 1, self.indices.shape[1] - 1
        for rows, cols in self._dirty:
            r0, r1, _ = rows.indices(gh + 1)
            c0, c1, _ = cols.indices(gw + 1)
            if r1 <= r0 or c1 <= c0:
                continue
            box = np.ascontiguousarray(self.indices[r0:r1, c0:c1], np.uint8)
            self._grid.write(box.tobytes(), viewport=(c0, r0, c1 - c0, r1 - r0))
            crow, ccol = dirty_cells(GridChange(slice(r0, r1), slice(c0, c1)), (gh, gw))
            if crow.stop <= crow.start or ccol.stop <= ccol.start:
                continue
            splits = region_splits(self.indices, None, self.saddle,
                                   (crow.start, crow.stop - 1, ccol.start, ccol.stop - 1))
            box = (ccol.start, crow.start, ccol.stop - ccol.start, crow.stop - crow.start)
            self._splits.write(splits.tobytes(), viewport=box)
            self.uploaded.append(box)
            if self.base is not None:
                n, m = self.cell
                self.base.update((box[0] * n, box[1] * m, box[2] * n, box[3] * m))
        self._dirty.clear()

    def set_colour_map(self, colour_map: ColourMap | None,
                       region: tuple[int, int, int, int] | None) -> bool:
        """Show ``colour_map`` instead (a map made neutral under an edit), redrawing ``region``.

        Returns False when the view cannot take it in place (a map appears or
        goes: the shader variant changes), so the caller builds a new view.
        """
        if (colour_map is None) != (self.style.colour_map is None):
            return False
        self.style = self.style._replace(colour_map=colour_map)
        if self.base is not None:
            self.base.colour_map = colour_map
            self.base.update(region or (0, 0, *self.texture_size))
        return True

    # -- height map --------------------------------------------------------------
    def set_height_map(self, heights: np.ndarray | None, scale: float = 1.0) -> None:
        """Displace the ground by a grey image over the whole texture (None: flat, repeating).

        ``heights`` as :func:`.ground_mesh.grey_heights`; the ground rises ``value * scale`` texels.
        """
        old, self.heights = self.heights, None
        if old is not None:
            old.release()
        if heights is not None:
            self.heights = HeightField(self.ctx, heights, scale, self.texture_size,
                                       self.options.mesh)

    def ground_height(self, x: float, y: float) -> float:
        """The ground's height in texels under ground point ``(x, y)`` (0 without a height map)."""
        return 0.0 if self.heights is None else self.heights.height_at(x, y, self.texture_size)

    # -- drawing -----------------------------------------------------------------
    def draw(self, view: Camera | PlaneMapping, size: tuple[int, int], *,
             framebuffer: moderngl.Framebuffer | None = None, flip_y: bool = False,
             scale: float = 1.0) -> None:
        """Draw a ``size = (w, h)`` frame into ``framebuffer`` (default: this view's own).

        ``flip_y``: row 0 at the bottom, upright on a display; else the frame's top row in
        framebuffer row 0. ``scale`` < 1 draws that fraction of each side, stretched.
        """
        w, h = check_size(size)
        if scale < 1.0:
            small = (max(1, round(w * scale)), max(1, round(h * scale)))
            frame = self._reduced_target(small)
            self.draw(view, small, framebuffer=frame, flip_y=flip_y)
            target = framebuffer if framebuffer is not None else self._framebuffer(w, h)
            target.use()
            self.ctx.viewport = (0, 0, w, h)
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
            prog = self.pipeline.program(Variant("present"))
            self.pipeline.set_uniforms(prog, {"tt_target": (float(w), float(h))})
            frame.color_attachments[0].use(UNITS["tt_frame"])
            self._present.render(moderngl.TRIANGLES, vertices=3)
            return
        if self.heights is not None and not isinstance(view, Camera):
            raise TerrathemeError("a height map needs a Camera view (eq. 1 maps a flat plane)")
        mapping = view_mapping(view, (w, h), self.texture_size)
        self._flush()
        fbo = framebuffer if framebuffer is not None else self._framebuffer(w, h)
        fbo.use()
        self.ctx.viewport = (0, 0, w, h)
        mesh = self.heights is not None
        prog = self.pipeline.program(self._variant(mesh))
        self.textures.bind(self.style, True, self.sampler_anisotropy)
        self._grid.use(UNITS["tt_grid"])
        self._splits.use(UNITS["tt_splits"])
        gh, gw = self.indices.shape[0] - 1, self.indices.shape[1] - 1
        values = {"tt_cell": self.cell, "tt_block_cell": (0, 0), "tt_block_cells": (gw, gh),
                  **self.textures.uniforms(self.style, self.texture_size,
                                           self.options.max_supersample)}
        if self.base is not None:
            self.base.bind(self.sampler_anisotropy)
            values.update(self.base.uniforms())
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        if mesh:
            near, far = self.heights.depth_range(view, self.texture_size)
            clip = clip_matrix(view, (w, h), self.texture_size, near, far, flip_y=flip_y)
            values["tt_clip"] = tuple(clip.T.ravel())
            values["tt_height_scale"] = self.heights.scale
            self.pipeline.set_uniforms(prog, values)
            self.ctx.enable(moderngl.DEPTH_TEST)
            fbo.clear(*self.options.sky, 1.0, depth=1.0)
            self.heights.draw(prog)
            self.ctx.disable(moderngl.DEPTH_TEST)
        else:
            values["tt_plane"] = tuple(mapping.coefficients().ravel())
            values["tt_screen"] = (float(h), -1.0) if flip_y else (0.0, 1.0)
            values["tt_sky"] = tuple(float(c) for c in self.options.sky)
            self.pipeline.set_uniforms(prog, values)
            self.ctx.disable(moderngl.DEPTH_TEST)
            self._plane.render(moderngl.TRIANGLES, vertices=3)

    def _reduced_target(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        """A texture-backed framebuffer with depth of exactly ``size`` (the reduced frame)."""
        fbo = self._reduced
        if fbo is None or fbo.size != size:
            _release_framebuffer(fbo)
            colour = self.ctx.texture(size, 4)
            colour.filter = (moderngl.LINEAR, moderngl.LINEAR)
            colour.repeat_x = colour.repeat_y = False
            fbo = self._reduced = self.ctx.framebuffer(
                color_attachments=[colour], depth_attachment=self.ctx.depth_renderbuffer(size))
        if self._present is None:
            self._present = self.ctx.vertex_array(self.pipeline.program(Variant("present")), [])
        return fbo

    def _framebuffer(self, w: int, h: int) -> moderngl.Framebuffer:
        """An RGBA8 framebuffer with depth of at least ``w x h`` pixels."""
        fbo = self._fbo
        if fbo is None or fbo.width < w or fbo.height < h:
            _release_framebuffer(fbo)
            fbo = self._fbo = self.ctx.framebuffer(
                color_attachments=[self.ctx.renderbuffer((w, h), 4)],
                depth_attachment=self.ctx.depth_renderbuffer((w, h)))
        return fbo

    def render(self, view: Camera | PlaneMapping, size: tuple[int, int] = (640, 360),
               scale: float = 1.0) -> np.ndarray:
        """One frame read back: ``(h, w, 3) uint8``, row 0 at the top (``scale``: :meth:`draw`)."""
        w, h = check_size(size)
        self.draw(view, (w, h), scale=scale)
        rgba = np.empty((h, w, 4), np.uint8)
        self._fbo.read_into(rgba, viewport=(0, 0, w, h), components=4, alignment=1)
        return np.ascontiguousarray(rgba[..., :3])

    def release(self) -> None:
        """Free every GPU object of this view (the context stays)."""
        if self.heights is not None:
            self.heights.release()
            self.heights = None
        for fbo in (self._fbo, self._reduced):
            _release_framebuffer(fbo)
        self._fbo = self._reduced = None
        for obj in (self._plane, self._present, self._grid, self._splits, self.base):
            if obj is not None:
                obj.release()
        if self.base is not None:
            self._renderer.release()
            self.base = None
        self.pipeline.release()
        self.textures.release()
        self.themes.release()


def _release_framebuffer(fbo: moderngl.Framebuffer | None) -> None:
    """Free a framebuffer this view made and its attachments."""
    if fbo is not None:
        for attachment in (*fbo.color_attachments, fbo.depth_attachment):
            attachment.release()
        fbo.release()


def render_perspective_gpu(project: ThematicTexture, view: Camera | PlaneMapping,
                           size: tuple[int, int] = (640, 360), *,
                           options: GroundOptions = GroundOptions(),  # noqa: B008 (frozen)
                           heights: np.ndarray | None = None,
                           height_scale: float = 1.0) -> np.ndarray:
    """One perspective frame of a project on the GPU, headless: ``terratheme perspective``'s view.

    ``view``: a Camera or eq. 1 PlaneMapping in texels of the (repeating) texture; ``size``
    (w, h) pixels; ``heights`` (h, w), optional, a height map (``view`` then a Camera),
    ``height_scale`` texels per unit. Returns (h, w, 3) uint8, row 0 on top, sky above
    the horizon.
    """
    ground = GroundView.from_project(project, options)
    try:
        if heights is not None:
            ground.set_height_map(heights, height_scale)
        return ground.render(view, size)
    finally:
        ground.release()
