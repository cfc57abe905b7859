"""The shader programs of the GPU renderer, compiled once per context and variant.

A variant is the fragment shader (``tt_terrain.frag.glsl``, the blend rule
per pixel, or ``tt_copy.frag.glsl``, the copy of uniform cells), the
blend (``TT_BLEND``), the sampling path (``TT_FILTERED``), the colour map
switch (``TT_COLOUR_MAP``), the theme count (``TT_THEMES``) and whether
every theme has one size (``TT_ONE_SIZE``); every variant uses
``tt_rect.vert.glsl``.
"""

from __future__ import annotations

import moderngl
import numpy as np

from core.errors import TerrathemeError
from core.gpu.shaders import shader_source

#: texture unit of every sampler uniform (the renderer binds its textures there)
UNITS = {"tt_grid": 0, "tt_splits": 1, "tt_themes": 2, "tt_gauss": 3, "tt_inverse_lut": 4,
         "tt_colour_map": 5, "tt_theme": 6}
#: fragment shader of each program kind
FRAGMENT = {"blend": "tt_terrain.frag.glsl", "copy": "tt_copy.frag.glsl"}


def compile_program(ctx: moderngl.Context, kind: str, *, themes: int, histogram: bool,
                    filtered: bool, colour_map: bool = False, one_size: bool = False,
                    lut_size: int = 4096) -> moderngl.Program:
    """Compile and link one variant, its samplers bound to :data:`UNITS`.

    Raises
    ------
    TerrathemeError
        The driver cannot compile the shaders (the first line of its log).
    """
    defines = {"TT_THEMES": themes, "TT_BLEND": int(histogram), "TT_FILTERED": int(filtered),
               "TT_COLOUR_MAP": int(colour_map), "TT_ONE_SIZE": int(one_size),
               "TT_LUT_SIZE": lut_size}
    try:
        prog = ctx.program(vertex_shader=shader_source("tt_rect.vert.glsl", defines),
                           fragment_shader=shader_source(FRAGMENT[kind], defines))
    except moderngl.Error as exc:
        log = [ln for ln in str(exc).splitlines() if ln.strip()]
        raise TerrathemeError(f"GPU shader {FRAGMENT[kind]} does not compile on this driver: "
                              f"{log[-1] if log else exc}") from None
    for name, unit in UNITS.items():
        set_uniform(prog, name, unit)
    return prog


def set_uniform(prog: moderngl.Program, name: str, value: object) -> None:
    """Set a uniform if the program uses it (drivers drop unused ones and array tails).

    Arrays are written as bytes, as many entries as the linked program kept.
    """
    member = prog.get(name, None)
    if member is None:
        return
    if isinstance(value, np.ndarray):
        member.write(np.ascontiguousarray(value[: member.array_length]).tobytes())
    else:
        member.value = value
