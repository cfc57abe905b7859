"""The GPU renderer (GLSL through moderngl/EGL) against the CPU renderer, texel for texel.

The CPU renderer is checked against an independent exact reference in
test_render.py; here the shaders must give its texels: exactly for the linear
blend (integer arithmetic in the shader), within one level for the
histogram-preserving blend (float32 sums). Every test that draws skips with
the reason when no OpenGL 3.3 context can be made; CI makes one (llvmpipe).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import moderngl
import numpy as np
import pytest
from gpu_cases import ODD_THEMES, random_themes
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu import (
    GpuRenderer,
    GpuRenderOptions,
    GpuUnavailableError,
    Sampling,
    create_context,
    gl_context,
)
from terratheme.core.io.images import read_image
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.render.overview import render_overview
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells
from terratheme.core.render.rules import SaddleRule, cell_splits

REPO = Path(__file__).resolve().parents[1]
LINEAR, HISTOGRAM = BlendMode.LINEAR, BlendMode.HISTOGRAM


#: three themes of one size, not a power of two (REPEAT wraps them; the filtered path keeps them)
EVEN_THEMES = random_themes(2, [(24, 20)] * 3)


@pytest.fixture(scope="module")
def odd(gpu_renderer) -> GpuRenderer:
    return gpu_renderer(ODD_THEMES)


@pytest.fixture(scope="module")
def even(gpu_renderer) -> GpuRenderer:
    return gpu_renderer(EVEN_THEMES)


def _assert_same(cpu: np.ndarray, gpu: np.ndarray, blend: BlendMode) -> None:
    assert gpu.shape == cpu.shape and gpu.dtype == np.uint8
    diff = np.abs(cpu.astype(np.int16) - gpu)
    if blend is LINEAR:
        assert diff.max() == 0, f"{(diff > 0).sum()} texels differ"
    else:
        assert diff.max() <= 1


@pytest.mark.parametrize("blend", [LINEAR, HISTOGRAM])
@pytest.mark.parametrize("cell", [(4, 4), (5, 3), (1, 1), (1, 4), (7, 1), (3, 11), (16, 16)])
def test_random_grids_equal_cpu(odd, cell, blend):
    rng = np.random.default_rng(cell[0] * 31 + cell[1])
    grid = rng.integers(0, 4, (9, 12)).astype(np.uint8)
    grid[:4, :5] = 2  # a uniform block too
    cpu = render_cells(grid, ODD_THEMES, cell, options=RenderOptions(blend=blend))
    gpu = odd.render(grid, cell, options=GpuRenderOptions(blend=blend))
    _assert_same(cpu, gpu, blend)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 9), m=st.integers(1, 9),
       k=st.integers(1, 4), hist=st.booleans())
def test_random_grids_equal_cpu_hypothesis(odd, seed, n, m, k, hist):
    rng = np.random.default_rng(seed)
    grid = rng.integers(0, k, (int(rng.integers(2, 8)), int(rng.integers(2, 8))))
    blend = HISTOGRAM if hist else LINEAR
    cpu = render_cells(grid, ODD_THEMES, (n, m), options=RenderOptions(blend=blend))
    _assert_same(cpu, odd.render(grid, (n, m), options=GpuRenderOptions(blend=blend)), blend)


@pytest.mark.parametrize("blend", [LINEAR, HISTOGRAM])
def test_themes_of_one_size_wrap_exactly_far_out(even, blend):
    # One theme size: the shaders wrap with REPEAT, coordinates kept small per tile.
    rng = np.random.default_rng(11)
    grid = rng.integers(0, 3, (4, 8381)).astype(np.uint8)
    grid[:, 8370:8376] = 1
    region = (8_375_000 - 37, 5, 70, 40)  # near the largest coordinate, 2^23
    cpu = render_cells(grid, EVEN_THEMES, (1000, 16), region, options=RenderOptions(blend=blend))
    gpu = even.render(grid, (1000, 16), region, options=GpuRenderOptions(blend=blend))
    _assert_same(cpu, gpu, blend)


def test_every_split_and_saddle_rule(odd):
    # Uniform, main-only, anti-only, saddles both ways, three and four themes in a cell.
    grid = np.array([[0, 0, 1, 0, 1, 2, 0],
                     [0, 0, 0, 1, 0, 3, 1],
                     [1, 0, 1, 0, 0, 1, 2],
                     [1, 1, 0, 2, 2, 0, 3],
                     [0, 1, 1, 2, 0, 3, 3]], np.uint8)
    assert set(np.unique(cell_splits(grid))) == {0, 1, 2}
    # The two saddle rules split this grid's saddles differently.
    assert (cell_splits(grid, SaddleRule.MINORITY) != cell_splits(grid, SaddleRule.MAIN)).any()
    for rule in SaddleRule:
        for blend in (LINEAR, HISTOGRAM):
            cpu = render_cells(grid, ODD_THEMES, (6, 5),
                               options=RenderOptions(blend=blend, saddle=rule))
            gpu = odd.render(grid, (6, 5), options=GpuRenderOptions(blend=blend, saddle=rule))
            _assert_same(cpu, gpu, blend)


def test_thin_river_saddles_stay_connected(odd):
    # A diagonal river of theme 1 through theme 0: every crossing is a saddle.
    grid = np.zeros((8, 8), np.uint8)
    grid[np.arange(8), np.arange(8)] = 1
    grid[np.arange(7), np.arange(1, 8)] = 1
    cpu = render_cells(grid, ODD_THEMES, (8, 8))
    _assert_same(cpu, odd.render(grid, (8, 8)), LINEAR)


@pytest.mark.parametrize("blend", [LINEAR, HISTOGRAM])
def test_regions_equal_the_cpu_region(odd, blend):
    rng = np.random.default_rng(7)
    grid = rng.integers(0, 4, (14, 17)).astype(np.uint8)
    grid[3:11, 2:12] = 3  # long uniform runs: copies of several theme periods
    cell = (6, 5)
    options = GpuRenderOptions(blend=blend)
    full = odd.render(grid, cell, options=options)
    for _ in range(6):
        w, h = int(rng.integers(1, 60)), int(rng.integers(1, 40))
        x, y = int(rng.integers(0, 16 * 6 - w + 1)), int(rng.integers(0, 13 * 5 - h + 1))
        cpu = render_cells(grid, ODD_THEMES, cell, (x, y, w, h), options=RenderOptions(blend=blend))
        gpu = odd.render(grid, cell, (x, y, w, h), options=options)
        _assert_same(cpu, gpu, blend)
        assert np.array_equal(gpu, full[y : y + h, x : x + w])


@pytest.mark.parametrize("blend", [LINEAR, HISTOGRAM])
def test_tiles_change_nothing(odd, blend):
    rng = np.random.default_rng(3)
    grid = rng.integers(0, 4, (10, 10)).astype(np.uint8)
    grid[2:7, 2:8] = 1
    ref = render_cells(grid, ODD_THEMES, (7, 6), options=RenderOptions(blend=blend))
    tiled = odd.render(grid, (7, 6), (3, 2, 50, 41),
                       options=GpuRenderOptions(blend=blend, tile=9))
    _assert_same(ref[2:43, 3:53], tiled, blend)


def test_index_grid_out_buffer_and_progress(odd):
    grid = IndexGrid(np.array([[0, 1, 2], [3, 0, 1]], np.uint8), (5, 4))
    out = np.zeros((4, 10, 3), np.uint8)
    calls = []
    got = odd.render(grid, out=out, options=GpuRenderOptions(tile=4),
                     progress=lambda d, t: calls.append((d, t)))
    assert got is out
    assert calls == [(1, 3), (2, 3), (3, 3)]
    assert np.array_equal(out, render_cells(grid, ODD_THEMES))


def test_filtered_path_at_scale_one_is_within_one_level(even):
    # A one-texel box mean is the texel; weights in 1/4096.
    rng = np.random.default_rng(5)
    grid = rng.integers(0, 3, (7, 9)).astype(np.uint8)
    for blend in (LINEAR, HISTOGRAM):
        cpu = render_cells(grid, EVEN_THEMES, (16, 8), options=RenderOptions(blend=blend))
        gpu = even.render(grid, (16, 8), options=GpuRenderOptions(
            blend=blend, sampling=Sampling.FILTERED))
        assert np.abs(cpu.astype(np.int16) - gpu).max() <= 1


@pytest.mark.parametrize("scale", [0.5, 1 / 3, 0.4, 0.15])
def test_flat_filtered_render_is_the_area_mean_of_themes_of_any_size(odd, scale):
    # Themes of odd sizes (7 x 5 ... 3 x 11) have no aligned mip levels: each output pixel
    # must still be its footprint's exact area mean (cv2's INTER_AREA on the full render).
    region = (5, 3, 60, 45)
    for k in range(len(ODD_THEMES)):
        grid = np.full((5, 6), k, np.uint8)
        full = render_cells(grid, ODD_THEMES, (13, 12), region)
        gpu = odd.render(grid, (13, 12), region, scale=scale)
        want = cv2.resize(full, gpu.shape[1::-1], interpolation=cv2.INTER_AREA)
        assert np.abs(want.astype(np.int16) - gpu).max() <= 1, f"theme {k}"


def test_filtered_path_at_scale_one_gives_the_texels_of_themes_of_any_size(odd):
    rng = np.random.default_rng(8)
    grid = rng.integers(0, 4, (7, 9)).astype(np.uint8)
    cpu = render_cells(grid, ODD_THEMES, (16, 8))
    gpu = odd.render(grid, (16, 8), options=GpuRenderOptions(sampling=Sampling.FILTERED))
    assert np.abs(cpu.astype(np.int16) - gpu).max() <= 1


def test_themes_too_large_for_box_sums_are_refused_in_one_line(gl_ctx):
    # 2901 x 2901 texels: a box of a whole theme (plus its edges) can sum past 2^31.
    renderer = GpuRenderer([np.zeros((2901, 2901, 3), np.uint8)])
    try:
        with pytest.raises(TerrathemeError, match="summed-area table .* beyond"):
            renderer.render(np.zeros((2, 2), np.uint8), (8, 8), scale=0.5)
    finally:
        renderer.release()


def test_filtered_overview_is_close_to_the_cpu_overview(even):
    # Both take each theme's box mean over the pixel (the GPU's fractional box and
    # sub-sampled weights in 1/4096): a level apart at a few pixels at most.
    rng = np.random.default_rng(6)
    grid = rng.integers(0, 3, (17, 21)).astype(np.uint8)
    for scale in (0.5, 0.25):
        cpu = render_overview(grid, EVEN_THEMES, (16, 16), scale=scale)
        gpu = even.render(grid, (16, 16), scale=scale)
        assert gpu.shape == cpu.shape
        assert np.abs(cpu.astype(np.int16) - gpu).mean() < 0.05


def test_draw_leaves_the_frame_in_the_framebuffer(odd):
    grid = np.array([[0, 1, 1], [2, 1, 1], [1, 1, 3]], np.uint8)
    fbo = odd.draw(grid, (9, 7), (2, 3, 15, 9))
    odd.ctx.finish()
    rgba = np.frombuffer(fbo.read(viewport=(0, 0, 15, 9), components=4), np.uint8)
    want = render_cells(grid, ODD_THEMES, (9, 7), (2, 3, 15, 9))
    assert np.array_equal(rgba.reshape(9, 15, 4)[..., :3], want)
    with pytest.raises(TerrathemeError, match="one tile"):
        odd.draw(grid, (9, 7), options=GpuRenderOptions(tile=8))


def test_colour_map_multiplies_by_value_over_128(even):
    grid = np.array([[0, 1, 2], [2, 0, 1], [1, 1, 0]], np.uint8)
    base = even.render(grid, (8, 8))
    neutral = even.render(grid, (8, 8), colour_map=ColourMap(np.full((2, 2, 3), 128, np.uint8), 8))
    assert np.array_equal(neutral, base)
    half = even.render(grid, (8, 8), colour_map=ColourMap(np.full((1, 1, 3), 64, np.uint8), 16))
    assert np.array_equal(half, (base.astype(np.int32) + 1) // 2)
    # Two map columns 64 | 192 at scale 8 over 16 texels: map coordinate (x + 0.5) / 8 - 0.5,
    # gains 0.5 and 1.5 at the columns' centres (texels 3.5 and 11.5), linear between.
    cmap = ColourMap(np.array([[[64, 64, 64], [192, 192, 192]]] * 2, np.uint8), 8)
    ramp = even.render(grid, (8, 8), colour_map=cmap)
    x = np.arange(16)
    pos = np.clip((x + 0.5) / 8 - 0.5, 0, 1)
    gain = (64 + 128 * pos) / 128
    want = np.minimum(np.floor(base * gain[None, :, None] + 0.5), 255)
    assert np.abs(ramp - want).max() == 0


def test_bad_inputs_are_refused_before_work(odd):
    grid = np.zeros((3, 3), np.uint8)
    with pytest.raises(TerrathemeError, match="theme"):
        odd.render(np.full((3, 3), 7), (4, 4))
    with pytest.raises(TerrathemeError, match="outside"):
        odd.render(grid, (4, 4), (0, 0, 9, 9))
    with pytest.raises(TerrathemeError, match="scale"):
        odd.render(grid, (4, 4), scale=0)
    with pytest.raises(TerrathemeError, match="exact sampling renders at scale 1"):
        odd.render(grid, (4, 4), scale=0.5, options=GpuRenderOptions(sampling=Sampling.EXACT))
    with pytest.raises(TerrathemeError, match="out must be"):
        odd.render(grid, (4, 4), out=np.zeros((8, 8, 4), np.uint8))
    with pytest.raises(TerrathemeError, match="colour map must be a ColourMap"):
        odd.render(grid, (4, 4), colour_map=np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(TerrathemeError, match="exact integer range"):
        # 2049 cells of the largest cell (4096 texels) pass 2^23 texels across.
        odd.render(np.zeros((2, 2050), np.uint8), (4096, 1))
    with pytest.raises(TerrathemeError, match="tile"):
        odd.render(grid, (4, 4), options=GpuRenderOptions(tile=0))
    with pytest.raises(TerrathemeError, match="cell size"):
        odd.render(grid, (0, 4))
    with pytest.raises(TerrathemeError, match="no themes"):
        GpuRenderer([])


def test_no_context_is_one_clear_error(monkeypatch):
    def fail(**kwargs):
        raise Exception("eglInitialize failed (0x3001)")

    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    with pytest.raises(GpuUnavailableError, match=r"no OpenGL 3\.3 context .*0x3001"):
        create_context()


@pytest.mark.parametrize("broken", [
    "LIBGL_DRIVERS_PATH",  # Mesa's loader finds no driver (and would print warnings)
    "__EGL_VENDOR_LIBRARY_FILENAMES",  # glvnd finds no EGL vendor at all
])
def test_cli_without_egl_driver_prints_one_line_and_exits_2(tmp_path, broken):
    env = {**os.environ, broken: str(tmp_path / "none")}
    project = REPO / "sample_maps" / "airfield.ttproj"
    out = subprocess.run([sys.executable, "-m", "terratheme.app.cli", "render", str(project),
                          str(tmp_path / "x.png"), "--gpu", "--region", "0,0,8,8"],
                         cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    if out.returncode == 0 and broken == "LIBGL_DRIVERS_PATH":
        pytest.skip("this machine's EGL driver is not Mesa's: the failure was not simulated")
    assert out.returncode == 2
    lines = [ln for ln in out.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "no OpenGL 3.3 context" in lines[0], out.stderr
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("extra", [[], ["--blend", "histogram"], ["--scale", "0.5"]])
def test_cli_gpu_render_matches_the_cpu_render(odd, tmp_path, capsys, extra):
    project = str(REPO / "sample_maps" / "airfield.ttproj")
    args = ["--region", "40,24,150,90", *extra]
    assert main(["render", project, str(tmp_path / "gpu.png"), "--gpu", *args]) == 0
    assert "GPU" in capsys.readouterr().out
    assert main(["render", project, str(tmp_path / "cpu.png"), *args]) == 0
    gpu, cpu = read_image(tmp_path / "gpu.png"), read_image(tmp_path / "cpu.png")
    assert gpu.shape == cpu.shape
    diff = np.abs(gpu.astype(np.int16) - cpu)
    if "--scale" in extra:
        assert diff.mean() < 2.0
    else:
        assert diff.max() <= 1


def test_shared_context_is_opengl_33(odd):
    ctx = gl_context()
    assert ctx is odd.ctx and ctx.version_code >= 330
