"""The shader programs of the GPU renderer, compiled once per context and :class:`Variant`.

A variant is a program kind (docs/gpu.md, "The shader files") and the compile-time
switches of ``tt_blend.glsl`` (``TT_BLEND``, ``TT_SHAPED``, ``TT_FILTERED``, ...).
"""

from __future__ import annotations

from typing import NamedTuple

import moderngl
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu.shaders import shader_source

#: texture unit of every sampler uniform (the renderer binds its textures there)
UNITS = {"tt_grid": 0, "tt_splits": 1, "tt_themes": 2, "tt_gauss": 3, "tt_inverse_lut": 4,
         "tt_colour_map": 5, "tt_height": 7, "tt_frame": 8,
         "tt_base": 9, "tt_packed": 10, "tt_points": 11, "tt_box": 12}
#: (vertex shader, fragment shader, extra defines) of each program kind
SOURCES = {
    "blend": ("tt_rect.vert.glsl", "tt_terrain.frag.glsl", {}),
    "ground": ("tt_ground.vert.glsl", "tt_ground.frag.glsl", {"TT_GROUND_MESH": 0}),
    "ground_mesh": ("tt_ground.vert.glsl", "tt_ground.frag.glsl", {"TT_GROUND_MESH": 1}),
    "present": ("tt_ground.vert.glsl", "tt_present.frag.glsl", {"TT_GROUND_MESH": 0}),
    "unpack": ("tt_rect.vert.glsl", "tt_unpack.frag.glsl", {"TT_POINTS": 0}),
    "lookup": ("tt_rect.vert.glsl", "tt_unpack.frag.glsl", {"TT_POINTS": 1}),
    "split": ("tt_rect.vert.glsl", "tt_split.frag.glsl", {"TT_MINORITY": 1}),
    "split_main": ("tt_rect.vert.glsl", "tt_split.frag.glsl", {"TT_MINORITY": 0}),
}


class Variant(NamedTuple):
    """One compiled program: its kind and the defines of ``tt_blend.glsl``."""

    kind: str
    histogram: bool = False
    shaped: bool = False
    filtered: bool = False
    wrap: bool = False
    colour_map: bool = False
    lut_size: int = 4096
    probes: int = 0
    base: bool = False
    box: int = 0

    def defines(self, themes: int, one_size: bool) -> dict[str, int]:
        """The ``#define`` values of this variant for ``themes`` themes."""
        return {"TT_THEMES": themes, "TT_BLEND": int(self.histogram),
                "TT_SHAPED": int(self.shaped), "TT_FILTERED": int(self.filtered),
                "TT_WRAP": int(self.wrap), "TT_COLOUR_MAP": int(self.colour_map),
                "TT_ONE_SIZE": int(one_size), "TT_LUT_SIZE": self.lut_size,
                "TT_PROBES": self.probes, "TT_BASE": int(self.base), "TT_BOX": self.box,
                **SOURCES[self.kind][2]}


def compile_program(ctx: moderngl.Context, variant: Variant, *, themes: int,
                    one_size: bool = False) -> moderngl.Program:
    """Compile and link one variant, samplers bound to :data:`UNITS` (errors: log's 1st line)."""
    vertex, fragment, _ = SOURCES[variant.kind]
    defines = variant.defines(themes, one_size)
    try:
        prog = ctx.program(vertex_shader=shader_source(vertex, defines),
                           fragment_shader=shader_source(fragment, defines))
    except moderngl.Error as exc:
        log = [ln for ln in str(exc).splitlines() if ln.strip()]
        raise TerrathemeError(f"GPU shader {fragment} does not compile on this driver: "
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
