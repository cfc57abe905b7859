"""The blend rule on the GPU: GLSL shaders and a headless renderer (docs/gpu.md).

Modules: ``context`` (the standalone EGL OpenGL context, one clear error
where none can be made), ``shaders`` (the GLSL files of ``shaders/``, with
defines and includes), ``programs`` (compiled variants), ``pipeline`` (the
programs, textures and buffers a renderer reuses between frames),
``textures`` (themes, Gaussianised themes, inverse tables, colour map as
textures), ``cover`` (rectangles of uniform and blended cells),
``copy_image`` (uniform cells as image copies), ``options``
(sampling path, blend, tiles), ``renderer`` (:class:`GpuRenderer`,
:func:`render_cells_gpu`: a full texture or any region, exact at scale 1,
filtered with mipmaps and anisotropy below or on request).
"""

from core.gpu.context import GpuUnavailableError, create_context, gl_context
from core.gpu.options import GpuRenderOptions, Sampling, UniformCells
from core.gpu.renderer import GpuRenderer, render_cells_gpu
from core.gpu.shaders import SHADER_DIR, shader_source

__all__ = [
    "SHADER_DIR",
    "GpuRenderOptions",
    "GpuRenderer",
    "GpuUnavailableError",
    "Sampling",
    "UniformCells",
    "create_context",
    "gl_context",
    "render_cells_gpu",
    "shader_source",
]
