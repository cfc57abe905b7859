"""The GLSL sources of the GPU renderer, read from ``core/gpu/shaders/*.glsl``.

Defines go after ``#version`` and ``#include`` lines are expanded, as an engine's
shader preprocessor would (docs/gpu.md).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

from terratheme.core.errors import TerrathemeError

#: the folder of the shader files
SHADER_DIR = Path(__file__).resolve().parent / "shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')


def _expand(name: str, seen: tuple[str, ...]) -> list[str]:
    path = SHADER_DIR / name
    if name in seen or not path.is_file():
        raise TerrathemeError(f"shader {name}: missing or included twice ({' -> '.join(seen)})")
    out = []
    for line in path.read_text().splitlines():
        m = _INCLUDE.match(line)
        out.extend(_expand(m.group(1), (*seen, name)) if m else [line])
    return out


def shader_source(name: str, defines: Mapping[str, int | float | str] | None = None) -> str:
    """Shader file ``name`` with ``defines`` as ``#define`` lines and includes expanded."""
    lines = _expand(name, ())
    if not lines or not lines[0].startswith("#version"):
        raise TerrathemeError(f"shader {name}: the first line must be #version")
    macros = [f"#define {key} {value}" for key, value in (defines or {}).items()]
    return "\n".join([lines[0], *macros, *lines[1:]]) + "\n"
