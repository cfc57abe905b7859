"""The blend rule on the GPU: GLSL shaders and a headless renderer (docs/gpu.md).

:class:`GpuRenderer` renders a texture or a region (exact at
scale 1, filtered below), from a dense grid or a packed layer (:class:`PackedGrid`);
:class:`GroundView` / :func:`render_perspective_gpu` draw it on a ground plane in
perspective (the fly-over).
"""

from terratheme.core.gpu.context import GpuUnavailableError, create_context, gl_context
from terratheme.core.gpu.ground import GroundView, render_perspective_gpu
from terratheme.core.gpu.options import (
    Anisotropy,
    GpuRenderOptions,
    GroundOptions,
    Sampling,
)
from terratheme.core.gpu.packed import PackedGrid
from terratheme.core.gpu.renderer import GpuRenderer
from terratheme.core.gpu.shaders import SHADER_DIR, shader_source

__all__ = [
    "SHADER_DIR",
    "Anisotropy",
    "GpuRenderOptions",
    "GpuRenderer",
    "GpuUnavailableError",
    "GroundOptions",
    "GroundView",
    "PackedGrid",
    "Sampling",
    "create_context",
    "gl_context",
    "render_perspective_gpu",
    "shader_source",
]
