"""The OpenGL objects a renderer keeps between renders: programs, index textures, buffers.

A viewport redraws every frame; making these afresh would cost as much as drawing.
"""

from __future__ import annotations

import cv2
import moderngl
import numpy as np
from terratheme.core.gpu.programs import UNITS, Variant, compile_program, set_uniform

#: one vertex of a drawn rectangle: its texel-edge position
VERTEX = np.dtype([("edge", "<f4", 2)])


#: the two triangles of a rectangle, as (x, y) picks of (x0, y0, x1, y1)
_CORNERS = np.array([(0, 1), (2, 1), (0, 3), (0, 3), (2, 1), (2, 3)])


def rect_vertices(edges: np.ndarray) -> np.ndarray:
    """(6R,) :data:`VERTEX` array: two triangles per rectangle ``x0, y0, x1, y1`` of ``edges``."""
    edges = np.asarray(edges, dtype=np.float64)
    out = np.zeros(6 * len(edges), VERTEX)
    out["edge"] = edges[:, _CORNERS].reshape(-1, 2)
    return out


def capacity(n: int) -> int:
    """Room for ``n`` rounded up to a power of two (at least 64), so growth is rare."""
    return max(64, 1 << (max(n, 1) - 1).bit_length())


class Pipeline:
    """Programs, reusable textures, the vertex buffer and the framebuffer of one renderer,
    compiled for ``themes`` themes (``TT_THEMES``), all of one size when ``one_size``.
    """

    def __init__(self, ctx: moderngl.Context, themes: int, one_size: bool) -> None:
        self.ctx = ctx
        self.themes = themes
        self.one_size = one_size
        self._programs: dict[Variant, moderngl.Program] = {}
        self._uniforms: dict[int, dict[str, object]] = {}
        self._index: dict[str, moderngl.Texture] = {}
        self._buffer: moderngl.Buffer | None = None
        self._vaos: dict[int, moderngl.VertexArray] = {}
        self._fbo: moderngl.Framebuffer | None = None
        self._scratch = np.empty((0, 0, 4), np.uint8)

    def program(self, variant: Variant) -> moderngl.Program:
        """The compiled variant (``core.gpu.programs``), made once."""
        if variant not in self._programs:
            self._programs[variant] = compile_program(self.ctx, variant, themes=self.themes,
                                                      one_size=self.one_size)
        return self._programs[variant]

    def set_uniforms(self, prog: moderngl.Program, values: dict[str, object]) -> None:
        """Send the uniforms that changed since this program's last draw."""
        sent = self._uniforms.setdefault(prog.glo, {})
        for name, value in values.items():
            old = sent.get(name)
            same = (np.array_equal(old, value) if isinstance(value, np.ndarray)
                    else old == value)
            if old is None or not same:
                set_uniform(prog, name, value)
                sent[name] = value.copy() if isinstance(value, np.ndarray) else value

    def index_texture(self, name: str, values: np.ndarray) -> moderngl.Texture:
        """``values`` ((h, w) uint8) in the corner of a reused R8UI texture bound to its unit."""
        h, w = values.shape
        tex = self._index.get(name)
        if tex is None or tex.width < w or tex.height < h:
            if tex is not None:
                tex.release()
            tex = self.ctx.texture((capacity(w), capacity(h)), 1, dtype="u1")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._index[name] = tex
        tex.write(np.ascontiguousarray(values, dtype=np.uint8).tobytes(), viewport=(0, 0, w, h))
        tex.use(UNITS[name])
        return tex

    def upload_vertices(self, vertices: np.ndarray) -> None:
        """Write this tile's vertices (:data:`VERTEX` records) to the reused vertex buffer."""
        size = vertices.nbytes
        if self._buffer is None or self._buffer.size < size:
            if self._buffer is not None:
                for vao in self._vaos.values():
                    vao.release()
                self._vaos.clear()
                self._buffer.release()
            self._buffer = self.ctx.buffer(reserve=capacity(size))
        self._buffer.write(vertices.tobytes())

    def draw(self, prog: moderngl.Program, first: int, count: int) -> None:
        """Draw vertices ``[first, first + count)`` of the buffer as triangles with ``prog``."""
        vao = self._vaos.get(prog.glo)
        if vao is None:
            vao = self._vaos[prog.glo] = self.ctx.vertex_array(
                prog, [(self._buffer, "2f", "tt_edge")], skip_errors=True)
        vao.render(moderngl.TRIANGLES, vertices=count, first=first)

    def framebuffer(self, w: int, h: int) -> moderngl.Framebuffer:
        """An RGBA8 framebuffer of at least ``w x h`` pixels, made current."""
        fbo = self._fbo
        if fbo is None or fbo.width < w or fbo.height < h:
            if fbo is not None:
                fbo.release()
            fbo = self._fbo = self.ctx.simple_framebuffer((w, h), components=4)
        fbo.use()
        return fbo

    def read(self, image: np.ndarray, tx: int, ty: int, tw: int, th: int) -> None:
        """Copy the framebuffer's first ``tw x th`` pixels into ``image[ty:, tx:]`` (RGB)."""
        if self._scratch.shape[0] < th or self._scratch.shape[1] != tw:
            self._scratch = np.empty((th, tw, 4), np.uint8)
        rgba = self._scratch[:th]
        self._fbo.read_into(rgba, viewport=(0, 0, tw, th), components=4, alignment=1)
        view = image[ty : ty + th, tx : tx + tw]
        rgb = cv2.cvtColor(rgba, cv2.COLOR_RGBA2RGB, dst=view)
        if not np.shares_memory(rgb, view):
            view[...] = rgb

    def release(self) -> None:
        """Free every object kept."""
        for obj in [*self._vaos.values(), *self._programs.values(), *self._index.values()]:
            obj.release()
        for obj in (self._buffer, self._fbo):
            if obj is not None:
                obj.release()
        self._vaos.clear()
        self._programs.clear()
        self._index.clear()
        self._uniforms.clear()
        self._buffer = self._fbo = None
