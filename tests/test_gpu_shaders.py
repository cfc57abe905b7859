"""The shader files of the GPU renderer (no OpenGL context needed)."""

from __future__ import annotations

import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu import SHADER_DIR, shader_source

ENTRY_POINTS = ["tt_terrain.frag.glsl", "tt_rect.vert.glsl"]


@pytest.mark.parametrize("name", ENTRY_POINTS)
def test_defines_follow_the_version_line_and_includes_are_expanded(name):
    src = shader_source(name, {"TT_THEMES": 5, "TT_BLEND": 1})
    lines = src.splitlines()
    assert lines[0] == "#version 330 core"
    assert lines[1:3] == ["#define TT_THEMES 5", "#define TT_BLEND 1"]
    assert "#include" not in src.replace("`#include`", "")
    if name.endswith(".frag.glsl"):
        assert "vec4 tt_shade(vec2 p)" in src and "main()" in src


def test_every_shader_file_documents_its_inputs():
    for path in SHADER_DIR.glob("*.glsl"):
        head = path.read_text().splitlines()[:12]
        assert sum(ln.startswith("//") for ln in head) >= 5, path.name


def test_missing_include_is_an_error(tmp_path, monkeypatch):
    (tmp_path / "a.glsl").write_text('#version 330 core\n#include "b.glsl"\n')
    monkeypatch.setattr("terratheme.core.gpu.shaders.SHADER_DIR", tmp_path)
    with pytest.raises(TerrathemeError, match=r"b\.glsl: missing"):
        shader_source("a.glsl")
    (tmp_path / "b.glsl").write_text('#include "a.glsl"\n')
    with pytest.raises(TerrathemeError, match="included twice"):
        shader_source("a.glsl")

