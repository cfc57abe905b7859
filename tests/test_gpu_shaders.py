"""The shader files and the cell cover of the GPU renderer (no OpenGL context needed)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu import SHADER_DIR, shader_source
from terratheme.core.gpu.cover import BLENDED, cell_rectangles
from terratheme.core.render.rules import cell_splits

REPO = Path(__file__).resolve().parents[1]
ENTRY_POINTS = ["tt_terrain.frag.glsl", "tt_copy.frag.glsl", "tt_rect.vert.glsl"]


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


def test_shaders_ship_as_package_data():
    config = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert "gpu/shaders/*.glsl" in config["tool"]["setuptools"]["package-data"]["terratheme.core"]


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31), h=st.integers(2, 12), w=st.integers(2, 12),
       k=st.integers(1, 3), block=st.integers(1, 4))
def test_rectangles_cover_every_cell_once_with_its_theme(seed, h, w, k, block):
    rng = np.random.default_rng(seed)
    coarse = rng.integers(0, k, (h, w)).astype(np.uint8)
    grid = np.kron(coarse, np.ones((block, block), np.uint8))[: h + 1, : w + 1]
    if grid.shape[0] < 2 or grid.shape[1] < 2:
        return
    splits = cell_splits(grid)
    rects, themes = cell_rectangles(grid, splits)
    cover = np.zeros(splits.shape, int)
    kind = np.full(splits.shape, -9)
    for (x0, y0, x1, y1), t in zip(rects, themes, strict=True):
        assert x0 < x1 and y0 < y1
        cover[y0:y1, x0:x1] += 1
        kind[y0:y1, x0:x1] = t
    assert (cover == 1).all()
    want = np.where(splits == 0, grid[:-1, :-1].astype(int), BLENDED)
    assert np.array_equal(kind, want)


def test_uniform_block_is_one_rectangle():
    grid = np.full((6, 9), 3, np.uint8)
    rects, themes = cell_rectangles(grid, cell_splits(grid))
    assert rects.tolist() == [[0, 0, 8, 5]] and themes.tolist() == [3]
