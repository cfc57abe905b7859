"""A packed index layer read by the shaders, never unpacked (docs/gpu.md, "Packed layers").

The layer's random-access table goes to the GPU as it is (an ``R32UI`` texture 4096
words wide); per tile, the GPU decodes the block into the blend shader's ``tt_grid``
and splits its cells into ``tt_splits``, so the blend pass is the dense render's own.
"""

from __future__ import annotations

import moderngl
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu.pipeline import capacity, rect_vertices
from terratheme.core.gpu.programs import UNITS, Variant, compile_program, set_uniform
from terratheme.core.packing import PackedLayer, TiledLayer
from terratheme.core.render.rules import SaddleRule

#: log2 of the table texture's width (``TT_PACKED_ROW_BITS`` of ``tt_packed.glsl``)
ROW_BITS = 12
#: width of the points texture of :meth:`PackedGrid.lookup`
POINT_ROW = 1024


def check_grid_layer(layer: PackedLayer | TiledLayer, themes: int) -> None:
    """Refuse (TerrathemeError) a layer that cannot be a vertex index grid over ``themes`` themes:
    tiled, not a 2-D identity layer, under 2 x 2 vertices, or an index not below ``themes``.
    Reads the runs' indices only, never the texels.
    """
    if isinstance(layer, TiledLayer):
        raise TerrathemeError("a tiled packed layer: the GPU reads single packed layers "
                              "(up to 65536 vertices a side)")
    if layer.channels != 1:
        raise TerrathemeError("a packed index grid must be an index layer (one channel, the "
                              "texel value its palette index), not a colour layer")
    if not layer.identity:
        raise TerrathemeError(f"a packed index grid must be an index layer (the texel value "
                              f"its palette index); this one holds {layer.palette.dtype} "
                              f"values through a palette, as a grey image does")
    if layer.width < 2 or layer.height < 2:
        raise TerrathemeError(f"a packed index grid needs at least 2 x 2 vertices, got "
                              f"{layer.width} x {layer.height}")
    top = int(layer.P.max())
    if top >= themes:
        raise TerrathemeError(f"the packed index grid uses theme {top}, but only {themes} "
                              f"themes are loaded")


class PackedGrid:
    """One packed layer's table on the GPU, with the programs that read it.

    ``layer``: any index PackedLayer (a vertex grid for :meth:`bind_block`). Raises
    TerrathemeError when the table is taller than the driver's largest texture.
    """

    def __init__(self, ctx: moderngl.Context, layer: PackedLayer) -> None:
        self.ctx = ctx
        self.layer = layer
        table = layer.table
        row = 1 << ROW_BITS
        rows = -(-table.size // row)
        if rows > ctx.info["GL_MAX_TEXTURE_SIZE"]:
            raise TerrathemeError(f"the packed layer's table ({table.size:,} words) does not "
                                  f"fit one {row} x {ctx.info['GL_MAX_TEXTURE_SIZE']} texture")
        words = np.zeros(rows * row, np.uint32)
        words[: table.size] = table
        self.texture = ctx.texture((row, rows), 1, words.tobytes(), dtype="u4")
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        # One rectangle over the whole target, drawn by every pass.
        quad = rect_vertices(np.array([[0, 0, 1, 1]]))
        self._quad = ctx.buffer(quad.tobytes())
        self._programs: dict[str, tuple[moderngl.Program, moderngl.VertexArray]] = {}
        self._targets: dict[str, tuple[moderngl.Texture, moderngl.Framebuffer]] = {}
        self._points: moderngl.Texture | None = None

    def _program(self, kind: str) -> moderngl.Program:
        """The program of ``kind`` (``unpack``, ``lookup``, ``split``, ``split_main``)."""
        if kind not in self._programs:
            prog = compile_program(self.ctx, Variant(kind), themes=1)
            vao = self.ctx.vertex_array(prog, [(self._quad, "2f", "tt_edge")],
                                        skip_errors=True)
            self._programs[kind] = (prog, vao)
        return self._programs[kind][0]

    def _target(self, name: str, size: tuple[int, int], dtype: str) -> moderngl.Texture:
        """An unsigned-integer texture of at least ``size`` texels, its framebuffer current."""
        tex, fbo = self._targets.get(name, (None, None))
        if tex is None or tex.width < size[0] or tex.height < size[1]:
            if tex is not None:
                fbo.release()
                tex.release()
            tex = self.ctx.texture((capacity(size[0]), capacity(size[1])), 1, dtype=dtype)
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            fbo = self.ctx.framebuffer(color_attachments=[tex])
            self._targets[name] = (tex, fbo)
        fbo.use()
        self.ctx.viewport = (0, 0, *size)
        return tex

    def _pass(self, kind: str, target: str, size: tuple[int, int], dtype: str,
              uniforms: dict[str, object]) -> moderngl.Texture:
        """Draw program ``kind`` over ``size`` texels of ``target``; returns that texture."""
        prog = self._program(kind)
        tex = self._target(target, size, dtype)
        self.texture.use(UNITS["tt_packed"])
        for name, value in {"tt_view": (0.0, 0.0, 1.0, 1.0), **uniforms}.items():
            set_uniform(prog, name, value)
        self._programs[kind][1].render(moderngl.TRIANGLES, vertices=6)
        return tex

    def bind_block(self, cells: tuple[int, int, int, int], saddle: SaddleRule) -> None:
        """Decode inclusive cells ``(cx0, cy0, cx1, cy1)`` into ``tt_grid`` (vertex ``(cx0 + i,
        cy0 + j)`` at texel ``(i, j)``) and ``tt_splits`` (their cells' splits), bound as the dense
        render binds them. Leaves the last pass's framebuffer current.
        """
        cx0, cy0, cx1, cy1 = cells
        grid = self._pass("unpack", "tt_grid", (cx1 - cx0 + 2, cy1 - cy0 + 2), "u1",
                          {"tt_origin": (cx0, cy0)})
        grid.use(UNITS["tt_grid"])
        kind = "split" if saddle is SaddleRule.MINORITY else "split_main"
        splits = self._pass(kind, "tt_splits", (cx1 - cx0 + 1, cy1 - cy0 + 1), "u1",
                            {"tt_origin": (cx0, cy0)})
        splits.use(UNITS["tt_splits"])

    def lookup(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """(n,) int64 palette index of texels ``(xs[k], ys[k])`` (row 0 = top, -1 outside), found
        by the shader: the check that the GPU reads the table as the CPU does.
        """
        xs = np.asarray(xs, np.int64).ravel()
        ys = np.asarray(ys, np.int64).ravel()
        if xs.shape != ys.shape:
            raise TerrathemeError(f"{xs.size} columns and {ys.size} rows: one of each per texel")
        if xs.size == 0:
            return np.zeros(0, np.int64)
        if np.abs(np.concatenate([xs, ys])).max() >= 1 << 31:
            raise TerrathemeError("lookup coordinates must fit 32-bit integers")
        w = min(POINT_ROW, xs.size)
        h = -(-xs.size // w)
        points = np.zeros((h * w, 2), np.int32)
        points[: xs.size, 0], points[: xs.size, 1] = xs, ys
        if self._points is not None:
            self._points.release()
        self._points = self.ctx.texture((w, h), 2, points.tobytes(), dtype="i4")
        self._points.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._points.use(UNITS["tt_points"])
        self._pass("lookup", "points", (w, h), "u4", {})
        fbo = self._targets["points"][1]
        raw = fbo.read(viewport=(0, 0, w, h), components=1, dtype="u4")
        found = np.frombuffer(raw, np.uint32)[: xs.size].astype(np.int64)
        found[found > 255] = -1
        return found

    def release(self) -> None:
        """Free the GPU objects (the context stays)."""
        for prog, vao in self._programs.values():
            vao.release()
            prog.release()
        for tex, fbo in self._targets.values():
            fbo.release()
            tex.release()
        for obj in (self._points, self._quad, self.texture):
            if obj is not None:
                obj.release()
        self._programs.clear()
        self._targets.clear()
        self._points = None
