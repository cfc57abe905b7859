"""The blend rule on the GPU: GLSL shaders and a headless renderer (docs/gpu.md).

Modules: ``context`` (the standalone EGL OpenGL context, one clear error
where none can be made), ``shaders`` (the GLSL files of ``shaders/``, with
defines and includes), ``programs`` (compiled variants), ``pipeline`` (the
programs, textures and buffers a renderer reuses between frames),
``textures`` (themes, Gaussianised themes, inverse tables, colour map as
textures), ``options``
(sampling path, blend, tiles), ``style`` (a project's blend, shaped borders
and colour map, checked against the shaders' integer ranges), ``plan`` (what a
render draws and each tile's geometry, no GPU), ``renderer``
(:class:`GpuRenderer`, :func:`render_cells_gpu`: a full texture or any
region, exact at scale 1, filtered with mipmaps and anisotropy below or on
request), ``packed`` (:class:`PackedGrid`: a packed index layer's table read by the
shaders, never unpacked; ``GpuRenderer.render`` takes a ``PackedLayer`` as
its grid), ``ground_mesh`` (a height map as a mesh), ``base_map`` (the render itself,
mipmapped, for wide footprints), ``ground`` (:class:`GroundView`,
:func:`render_perspective_gpu`: the texture on a ground plane in perspective).
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
from terratheme.core.gpu.renderer import GpuRenderer, render_cells_gpu
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
    "render_cells_gpu",
    "render_perspective_gpu",
    "shader_source",
]
