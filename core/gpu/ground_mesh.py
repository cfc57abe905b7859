"""A height map over the texture as a GPU mesh: the fly-over's displaced ground.

The map's pixel centres are aligned over the texture's extent (pixel ``(i, j)`` of a
``w x h`` map at ``((i + 0.5) W / w, (j + 0.5) H / h)``), read bilinearly and clamped
by the vertex shader, over at most ``mesh x mesh`` quads.
"""

from __future__ import annotations

import math

import cv2
import moderngl
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu.programs import UNITS
from terratheme.core.perspective import Camera


def grey_heights(heights: np.ndarray) -> np.ndarray:
    """(h, w) float32 heights: integers read as [0, 1], colour as grey; finite numbers only."""
    arr = np.asarray(heights)
    if arr.ndim == 3 and arr.shape[2] in (1, 2, 3, 4):
        # A grey image with alpha, or a colour image: its luminance (alpha dropped).
        arr = arr[..., 0] if arr.shape[2] <= 2 else cv2.cvtColor(
            np.ascontiguousarray(arr[..., :3]), cv2.COLOR_RGB2GRAY)
    if arr.ndim != 2 or 0 in arr.shape:
        raise TerrathemeError(f"height map must be a non-empty grey image, got shape "
                              f"{np.asarray(heights).shape}")
    if arr.dtype == np.bool_ or not np.issubdtype(arr.dtype, np.number):
        raise TerrathemeError(f"height map must hold numbers, got {arr.dtype}")
    if np.issubdtype(arr.dtype, np.integer):
        out = arr.astype(np.float32) / np.float32(np.iinfo(arr.dtype).max)
    else:
        out = arr.astype(np.float32)
    if not np.all(np.isfinite(out)):
        raise TerrathemeError("height map holds NaN or infinite values")
    return np.ascontiguousarray(out)


class HeightField:
    """A height map's texture and mesh on the GPU: ``heights`` as :func:`grey_heights`,
    ``scale`` texels of height per unit, over a ``texture_size`` (W, H) texture in at most
    ``mesh`` quads a side.
    """

    def __init__(self, ctx: moderngl.Context, heights: np.ndarray, scale: float,
                 texture_size: tuple[int, int], mesh: int) -> None:
        if not (math.isfinite(float(scale)) and float(scale) >= 0.0):
            raise TerrathemeError(f"height scale must be a finite number >= 0, got {scale}")
        self.values = grey_heights(heights)
        self.scale = float(scale)
        limit = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        if max(self.values.shape) > limit:
            raise TerrathemeError(f"height map {self.values.shape[1]} x {self.values.shape[0]}: "
                                  f"this OpenGL driver's textures are at most {limit} a side")
        self.ctx = ctx
        h, w = self.values.shape
        self.texture = ctx.texture((w, h), 1, self.values.tobytes(), dtype="f4")
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = False
        # The mesh: vertices at texel edges over the whole texture, two triangles per quad.
        nx, ny = min(int(mesh), max(1, w)), min(int(mesh), max(1, h))
        us = np.linspace(0.0, texture_size[0], nx + 1, dtype=np.float32)
        vs = np.linspace(0.0, texture_size[1], ny + 1, dtype=np.float32)
        grid = np.stack(np.meshgrid(us, vs), axis=-1).reshape(-1, 2)
        corner = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None, :]).ravel()
        quads = np.stack([corner, corner + 1, corner + nx + 1,
                          corner + nx + 1, corner + 1, corner + nx + 2], axis=1)
        self._vertices = ctx.buffer(np.ascontiguousarray(grid).tobytes())
        self._indices = ctx.buffer(quads.astype(np.uint32).tobytes())
        self._count = quads.size
        self._vaos: dict[int, moderngl.VertexArray] = {}

    @property
    def top(self) -> float:
        """The highest point of the ground in texels."""
        return float(self.values.max()) * self.scale

    def height_at(self, x: float, y: float, texture_size: tuple[int, int]) -> float:
        """The ground's height in texels at ground point ``(x, y)``, as the GPU samples it."""
        h, w = self.values.shape
        # Bilinear, pixel centres aligned, clamped at the edges (the sampler's LINEAR).
        px = min(max(x / texture_size[0] * w - 0.5, 0.0), w - 1.0)
        py = min(max(y / texture_size[1] * h - 0.5, 0.0), h - 1.0)
        i, j = min(int(px), w - 2) if w > 1 else 0, min(int(py), h - 2) if h > 1 else 0
        fx, fy = px - i, py - j
        v = self.values
        i1, j1 = min(i + 1, w - 1), min(j + 1, h - 1)
        top = v[j, i] * (1 - fx) + v[j, i1] * fx
        bottom = v[j1, i] * (1 - fx) + v[j1, i1] * fx
        return float(top * (1 - fy) + bottom * fy) * self.scale

    def depth_range(self, camera: Camera, texture_size: tuple[int, int]) -> tuple[float, float]:
        """``(near, far)`` along the view axis covering the mesh from ``camera``."""
        x = texture_size[0] / 2.0 if camera.x is None else float(camera.x)
        y = texture_size[1] / 2.0 if camera.y is None else float(camera.y)
        # The farthest mesh corner bounds far; the clearance over the highest point sets near.
        dx = max(abs(x), abs(x - texture_size[0]))
        dy = max(abs(y), abs(y - texture_size[1]))
        far = 1.5 * math.sqrt(dx * dx + dy * dy + (camera.height + self.top) ** 2) + 1.0
        clearance = camera.height - self.top
        near = max(0.05, 0.5 * clearance) if clearance > 0 else 0.05
        return min(near, far / 4.0), far

    def draw(self, prog: moderngl.Program) -> None:
        """Draw the mesh with ``prog`` (its height texture bound to ``tt_height``)."""
        vao = self._vaos.get(prog.glo)
        if vao is None:
            vao = self._vaos[prog.glo] = self.ctx.vertex_array(
                prog, [(self._vertices, "2f", "tt_edge")], index_buffer=self._indices,
                index_element_size=4)
        self.texture.use(UNITS["tt_height"])
        vao.render(moderngl.TRIANGLES, vertices=self._count)

    def release(self) -> None:
        """Free the texture, buffers and vertex arrays."""
        for vao in self._vaos.values():
            vao.release()
        self._vaos.clear()
        for obj in (self.texture, self._vertices, self._indices):
            obj.release()
