"""The GPU renderer in a project's own style: shaped borders and the colour map, texel for texel.

The CPU renderer's shaped borders and colour map are checked against
independent per-texel references in test_render_boundary.py and
test_colour_map.py; here the shaders must give its texels exactly (both are
integer arithmetic, done in 32-bit GLSL), on random grids, cells with N != M,
themes of odd sizes, regions, tiles and the extremes of the integer ranges.
Every test that draws skips with the reason when no OpenGL 3.3 context can be
made.
"""

from __future__ import annotations

import cv2
import moderngl
import numpy as np
import pytest
from gpu_cases import ODD_THEMES, random_themes
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu import GpuRenderer, GpuRenderOptions, Sampling
from terratheme.core.gpu.programs import set_uniform
from terratheme.core.gpu.shaders import SHADER_DIR
from terratheme.core.io.images import read_image, write_image
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.project import load_project
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.overview import render_overview
from terratheme.core.render.project import project_style, render_project
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells

SHAPED = BoundaryOptions()


@pytest.fixture(scope="module")
def odd(gpu_renderer) -> GpuRenderer:
    return gpu_renderer(ODD_THEMES)


def _colour_map(rng, texture_size: tuple[int, int], scale: int) -> ColourMap:
    mh, mw = ColourMap.shape_for(texture_size, scale)
    return ColourMap(rng.integers(0, 256, (mh, mw, 3), dtype=np.uint8), scale)


def _gpu(renderer, grid, cell, region=None, *, boundary=None, colour_map=None, **kwargs):
    options = GpuRenderOptions(boundary=boundary, **kwargs)
    return renderer.render(grid, cell, region, options=options, colour_map=colour_map)


def _cpu(grid, cell, region=None, *, boundary=None, colour_map=None):
    return render_cells(grid, ODD_THEMES, cell, region, options=RenderOptions(boundary=boundary),
                        colour_map=colour_map)


def _assert_equal(cpu: np.ndarray, gpu: np.ndarray) -> None:
    assert gpu.shape == cpu.shape and gpu.dtype == np.uint8
    diff = np.abs(cpu.astype(np.int16) - gpu)
    assert diff.max() == 0, f"{(diff > 0).sum()} values differ, by up to {diff.max()}"


@pytest.mark.parametrize("scale", [None, 1, 3, 8])
@pytest.mark.parametrize("cell", [(4, 4), (5, 3), (1, 1), (1, 4), (7, 1), (3, 11), (16, 16)])
def test_shaped_borders_and_colour_map_equal_cpu(odd, cell, scale):
    rng = np.random.default_rng(cell[0] * 31 + cell[1])
    grid = rng.integers(0, 4, (9, 12)).astype(np.uint8)
    grid[:4, :5] = 2  # a uniform block too
    size = (11 * cell[0], 8 * cell[1])
    cmap = None if scale is None else _colour_map(rng, size, scale)
    cpu = _cpu(grid, cell, boundary=SHAPED, colour_map=cmap)
    _assert_equal(cpu, _gpu(odd, grid, cell, boundary=SHAPED, colour_map=cmap))


@pytest.mark.parametrize("scale", [1, 2, 5])
def test_colour_map_alone_equals_cpu(odd, scale):
    # The paper's linear blend, multiplied by a map whose scale divides nothing.
    rng = np.random.default_rng(scale)
    grid = rng.integers(0, 4, (7, 10)).astype(np.uint8)
    cmap = _colour_map(rng, (9 * 7, 6 * 5), scale)
    _assert_equal(_cpu(grid, (7, 5), colour_map=cmap), _gpu(odd, grid, (7, 5), colour_map=cmap))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 9), m=st.integers(1, 9),
       k=st.integers(2, 4), width=st.floats(0.0, 12.0), noise=st.integers(0, 255),
       height=st.integers(0, 255), features=st.floats(0.05, 8.0),
       boundary_seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([None, 1, 2, 3, 7]))
def test_random_styles_equal_cpu_hypothesis(odd, seed, n, m, k, width, noise, height, features,
                                            boundary_seed, scale):
    rng = np.random.default_rng(seed)
    grid = rng.integers(0, k, (int(rng.integers(2, 8)), int(rng.integers(2, 8))))
    size = ((grid.shape[1] - 1) * n, (grid.shape[0] - 1) * m)
    boundary = BoundaryOptions(width=width, noise=noise, height=height, features=features,
                               seed=boundary_seed)
    cmap = None if scale is None else _colour_map(rng, size, scale)
    _assert_equal(_cpu(grid, (n, m), boundary=boundary, colour_map=cmap),
                  _gpu(odd, grid, (n, m), boundary=boundary, colour_map=cmap))


def test_regions_and_tiles_equal_the_cpu_region(odd):
    rng = np.random.default_rng(7)
    grid = rng.integers(0, 4, (14, 17)).astype(np.uint8)
    grid[3:11, 2:12] = 3
    cell = (6, 5)
    cmap = _colour_map(rng, (16 * 6, 13 * 5), 4)
    style = {"boundary": SHAPED, "colour_map": cmap}
    full = _gpu(odd, grid, cell, **style)
    for _ in range(6):
        w, h = int(rng.integers(1, 60)), int(rng.integers(1, 40))
        x, y = int(rng.integers(0, 16 * 6 - w + 1)), int(rng.integers(0, 13 * 5 - h + 1))
        region = (x, y, w, h)
        got = _gpu(odd, grid, cell, region, **style)
        _assert_equal(_cpu(grid, cell, region, **style), got)
        assert np.array_equal(got, full[y : y + h, x : x + w])
    tiled = _gpu(odd, grid, cell, (3, 2, 50, 41), tile=9, **style)
    assert np.array_equal(tiled, full[2:43, 3:53])


@pytest.mark.parametrize("cell, cells, features, scale", [
    ((4096, 2048), (2, 3), 0.094, 1448),  # lattice 32681 (near 2^15), cell area 2^23
    ((1000, 16), (4, 8380), 2.0, 1448),  # texels up to 2^23 across, largest colour scale
    ((3, 5), (400, 400), 0.025, 7),  # lattice 160 over small cells
])
def test_the_extremes_of_the_integer_ranges_stay_exact(odd, cell, cells, features, scale):
    # Products past 2^32 (1024 * W with W up to 2^23, 4 * noise sums up to 1020 L^2, the
    # colour map's v * G up to 2^39) are divided from their low 32 bits: still exact.
    rng = np.random.default_rng(cells[1])
    grid = rng.integers(0, 4, (cells[0] + 1, cells[1] + 1)).astype(np.uint8)
    size = (cells[1] * cell[0], cells[0] * cell[1])
    boundary = BoundaryOptions(features=features, width=40, seed=2**31 - 5)
    cmap = _colour_map(rng, size, scale)
    w, h = min(160, size[0]), min(90, size[1])
    for _ in range(2):
        region = (int(rng.integers(0, size[0] - w + 1)), int(rng.integers(0, size[1] - h + 1)),
                  w, h)
        style = {"boundary": boundary, "colour_map": cmap}
        _assert_equal(_cpu(grid, cell, region, **style), _gpu(odd, grid, cell, region, **style))


def test_filtered_path_draws_the_style_within_two_levels(odd):
    # Weights in 1/4096 and the hardware's bilinear colour map: close, not exact.
    themes = random_themes(2, [(24, 20)] * 3)
    renderer = GpuRenderer(themes)
    try:
        rng = np.random.default_rng(5)
        grid = rng.integers(0, 3, (7, 9)).astype(np.uint8)
        cmap = _colour_map(rng, (8 * 16, 6 * 8), 4)
        cpu = render_cells(grid, themes, (16, 8), options=RenderOptions(boundary=SHAPED),
                           colour_map=cmap)
        gpu = renderer.render(grid, (16, 8), colour_map=cmap, options=GpuRenderOptions(
            boundary=SHAPED, sampling=Sampling.FILTERED))
        diff = np.abs(cpu.astype(np.int16) - gpu)
        assert diff.max() <= 2 and diff.mean() < 0.5
        grid = rng.integers(0, 3, (17, 21)).astype(np.uint8)
        cmap = _colour_map(rng, (20 * 16, 16 * 16), 8)
        overview = render_overview(grid, themes, (16, 16), scale=0.25, colour_map=cmap)
        gpu = renderer.render(grid, (16, 16), scale=0.25, colour_map=cmap)
        # The map filtered over the pixel vs the CPU's at its centre: a fraction of a level.
        assert np.abs(overview.astype(np.int16) - gpu).mean() < 0.6
    finally:
        renderer.release()


def test_out_of_range_styles_are_refused_before_work(odd):
    grid = np.zeros((3, 3), np.uint8)
    with pytest.raises(TerrathemeError, match="noise lattice are beyond the GPU"):
        odd.render(grid, (64, 64), options=GpuRenderOptions(
            boundary=BoundaryOptions(features=0.001)))
    with pytest.raises(TerrathemeError, match=r"scale 2048 is beyond .*up to 1448"):
        odd.render(np.zeros((2, 2), np.uint8), (4096, 8),
                   colour_map=ColourMap(np.zeros((1, 2, 3), np.uint8), 2048))
    with pytest.raises(TerrathemeError, match="needs 2 x 2"):
        odd.render(grid, (4, 4), colour_map=ColourMap(np.zeros((3, 3, 3), np.uint8), 4))
    with pytest.raises(TerrathemeError, match="shaped boundaries blend linearly"):
        GpuRenderOptions(boundary=SHAPED, blend=BlendMode.HISTOGRAM)
    with pytest.raises(TerrathemeError, match="max_supersample"):
        GpuRenderOptions(max_supersample=0)


def _integer_program(ctx, body: str) -> moderngl.Program:
    """A one-row fragment program around tt_integer.glsl (inputs in textures, uint output)."""
    library = (SHADER_DIR / "tt_integer.glsl").read_text()
    vertex = ("#version 330 core\nvoid main() { vec2 p = vec2((gl_VertexID & 1) * 4 - 1, "
              "(gl_VertexID & 2) * 2 - 1); gl_Position = vec4(p, 0.0, 1.0); }\n")
    fragment = (f"#version 330 core\n{library}\nuniform usampler2D args;\n"
                f"uniform sampler2D estimate;\nout uvec2 f_out;\nvoid main() {{\n"
                f"  ivec2 at = ivec2(gl_FragCoord.xy);\n  uvec2 a = texelFetch(args, at, 0).rg;\n"
                f"  float e = texelFetch(estimate, at, 0).r;\n  {body}\n}}\n")
    return ctx.program(vertex_shader=vertex, fragment_shader=fragment)


def _run_integer(ctx, body: str, args: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    n = len(args)
    prog = _integer_program(ctx, body)
    src = ctx.texture((n, 1), 2, np.ascontiguousarray(args, np.uint32).tobytes(), dtype="u4")
    est = ctx.texture((n, 1), 1, np.ascontiguousarray(estimate, np.float32).tobytes(), dtype="f4")
    for tex in (src, est):
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    dst = ctx.texture((n, 1), 2, dtype="u4")
    fbo = ctx.framebuffer(color_attachments=[dst])
    try:
        fbo.use()
        ctx.viewport = (0, 0, n, 1)
        src.use(0)
        est.use(1)
        set_uniform(prog, "args", 0)
        set_uniform(prog, "estimate", 1)
        vao = ctx.vertex_array(prog, [])
        vao.render(moderngl.TRIANGLE_STRIP, vertices=4)
        out = np.frombuffer(dst.read(), np.uint32).reshape(n, 2)
        vao.release()
        return out
    finally:
        for obj in (prog, src, est, dst, fbo):
            obj.release()


@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_tt_quotient_divides_numbers_past_32_bits(odd, seed):
    # floor(A / b) for A up to 2^42 given only A mod 2^32 and a float estimate within 1.
    rng = np.random.default_rng(seed)
    n = 512
    b = rng.integers(1, 2**30 + 1, n, dtype=np.int64)
    b[:64] = 2**30
    quotient = rng.integers(0, 4096, n, dtype=np.int64)
    a = quotient * b + rng.integers(0, b)
    estimate = a / b + rng.uniform(-0.99, 0.99, n)
    estimate[:32] = a[:32] / b[:32]  # exact estimates too
    got = _run_integer(odd.ctx, "f_out = uvec2(tt_quotient(a.x, a.y, e), 0u);",
                       np.column_stack([a % 2**32, b]), estimate)
    assert np.array_equal(got[:, 0], a // b)


def test_tt_divmod_is_floor_division_for_negative_numbers_too(odd):
    rng = np.random.default_rng(3)
    a = rng.integers(-(2**24), 2**24, 2048, dtype=np.int64)
    b = rng.integers(1, 2**23, 2048, dtype=np.int64)
    b[:512] = rng.integers(1, 8, 512)
    body = ("ivec2 q = tt_divmod(int(a.x), int(a.y), 1.0 / float(int(a.y))); "
            "f_out = uvec2(q);")
    got = _run_integer(odd.ctx, body, np.column_stack([a % 2**32, b]), np.zeros(2048))
    assert np.array_equal(got[:, 0].astype(np.int32), a // b)
    assert np.array_equal(got[:, 1].astype(np.int64), a % b)


def _converted_project(tmp_path, block_photo):
    rng = np.random.default_rng(4)
    photo, _ = block_photo(rng, (6, 8), 24, 12.0)
    write_image(tmp_path / "photo.png", photo)
    assert main(["convert", str(tmp_path / "photo.png"), str(tmp_path / "p.ttproj"),
                 "--cell", "16"]) == 0
    return tmp_path / "p.ttproj"


def test_cli_gpu_renders_a_converted_project_in_its_own_style(odd, tmp_path, capsys,
                                                               block_photo):
    path = _converted_project(tmp_path, block_photo)
    project = load_project(path)
    assert project.colour_map is not None and project_style(project).boundary is not None
    capsys.readouterr()
    for extra in ([], ["--region", "5,7,100,61"], ["--blend", "linear"]):
        assert main(["render", str(path), str(tmp_path / "gpu.png"), "--gpu", *extra]) == 0
        assert "GPU" in capsys.readouterr().out
        assert main(["render", str(path), str(tmp_path / "cpu.png"), *extra]) == 0
        capsys.readouterr()
        gpu, cpu = read_image(tmp_path / "gpu.png"), read_image(tmp_path / "cpu.png")
        _assert_equal(cpu, gpu)
    # Below scale 1 the shaders draw the shaped borders too: close to the full render
    # area-averaged, as the CPU overview is (1.15 levels here). Fine detail themes of odd
    # sizes (33 x 33) read from misaligned mipmaps were 6.1 levels off.
    assert main(["render", str(path), str(tmp_path / "small.png"), "--gpu", "--scale",
                 "0.5"]) == 0
    small = read_image(tmp_path / "small.png")
    full = render_project(project)
    truth = cv2.resize(full, (small.shape[1], small.shape[0]), interpolation=cv2.INTER_AREA)
    assert np.abs(small.astype(np.int16) - truth).mean() < 2
