"""The OpenGL context of the GPU renderer: a standalone, headless EGL context (moderngl).

Any driver with OpenGL 3.3 core will do (Mesa's llvmpipe without a GPU); where none can
be made, :func:`create_context` raises :class:`GpuUnavailableError` with one line.
Mesa's own loader warnings are the caller's to silence (the CLI sets ``EGL_LOG_LEVEL``).
"""

from __future__ import annotations

import threading

import moderngl
from terratheme.core.errors import TerrathemeError

#: the OpenGL version the shaders need (GLSL 3.30 core)
REQUIRED_GL = 330

_shared: dict[int, moderngl.Context] = {}
_lock = threading.Lock()


class GpuUnavailableError(TerrathemeError):
    """No OpenGL 3.3 context can be made on this machine."""


def create_context() -> moderngl.Context:
    """A new standalone EGL OpenGL 3.3+ context; GpuUnavailableError (one line) if none."""
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=REQUIRED_GL)
    except Exception as exc:  # glcontext raises plain Exception
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise GpuUnavailableError(
            f"GPU rendering unavailable: no OpenGL 3.3 context could be made with EGL "
            f"({reason}); install Mesa's EGL (llvmpipe) or a GPU driver"
        ) from None
    return ctx


def gl_context() -> moderngl.Context:
    """The context shared by this thread's GPU renders, made on first use."""
    key = threading.get_ident()
    with _lock:
        ctx = _shared.get(key)
        if ctx is None:
            ctx = _shared[key] = create_context()
        return ctx
