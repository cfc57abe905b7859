"""The GPU reading a packed index layer (core.gpu.packed, tt_packed.glsl; issue 19).

The shader's lookups must be the CPU's (PackedLayer.lookup, itself checked
against the dense image in test_packing_table.py) on random coordinates,
both curves, odd sizes, quartered blocks and every grid block side; a
render from the packed layer must be the dense GPU render and the CPU
render, texel for texel. Skips with the reason where no OpenGL 3.3 context
can be made.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu import GpuRenderOptions, PackedGrid
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.packing import pack
from terratheme.core.packing.layout import W_GRID_BITS
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells
from terratheme.core.render.rules import SaddleRule, cell_splits

THEMES = [np.random.default_rng(k).integers(0, 256, (h, w, 3), dtype=np.uint8)
          for k, (w, h) in enumerate([(7, 5), (13, 17), (16, 16), (3, 11), (9, 9)])]


@pytest.fixture(scope="module")
def renderer(gpu_renderer):
    return gpu_renderer(THEMES)


def _image(rng, h: int, w: int, kind: str) -> np.ndarray:
    """Noise (many runs: small, quartered blocks), blobs (few: large blocks), or a mix."""
    if kind == "noise":
        return rng.integers(0, 5, (h, w)).astype(np.uint8)
    img = np.zeros((h, w), np.uint8)
    for _ in range(6):
        y, x = rng.integers(0, h), rng.integers(0, w)
        img[y : y + int(rng.integers(1, h + 1)), x : x + int(rng.integers(1, w + 1))] = \
            rng.integers(1, 5)
    if kind == "mixed":
        img[: h // 3, : w // 3] = rng.integers(0, 5, (h // 3, w // 3))
    return img


def _check_lookups(ctx, img: np.ndarray, curve: str, rng, n: int = 4000,
                   bits: int | None = None) -> int:
    layer = pack(img, curve=curve)
    if bits is not None:
        layer = layer.with_grid_bits(bits)
    h, w = img.shape
    xs = rng.integers(-4, w + 4, n)
    ys = rng.integers(-4, h + 4, n)
    inside = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
    grid = PackedGrid(ctx, layer)
    try:
        got = grid.lookup(xs, ys)
    finally:
        grid.release()
    want = np.full(n, -1)
    want[inside] = layer.lookup(xs[inside], ys[inside])
    assert np.array_equal(want[inside], img[ys[inside], xs[inside]])
    np.testing.assert_array_equal(got, want)
    return int(layer.table[W_GRID_BITS])


@pytest.mark.parametrize("curve", ["hilbert", "morton"])
@pytest.mark.parametrize("kind", ["noise", "blobs", "mixed"])
@pytest.mark.parametrize("shape", [(1, 1), (1, 37), (29, 3), (37, 53), (300, 211), (513, 1029)])
def test_shader_lookups_equal_cpu(gl_ctx, curve, kind, shape):
    rng = np.random.default_rng(zlib.crc32(repr((curve, kind, shape)).encode()))
    _check_lookups(gl_ctx, _image(rng, *shape, kind), curve, rng)


def test_every_grid_block_side_is_searched(gl_ctx):
    # Blocks of 2^4 .. 2^9 texels a side: odd sides walk the one-level Hilbert table first.
    rng = np.random.default_rng(5)
    seen = set()
    for density in (0.5, 0.05, 0.005, 0.0005, 0.00005, 0.0):
        img = (rng.random((700, 900)) < density).astype(np.uint8) * 3
        img[10:20, 10:600] = 1
        for curve in ("hilbert", "morton"):
            seen.add(_check_lookups(gl_ctx, img, curve, rng))
    assert {4, 5, 6, 7} <= seen


@pytest.mark.parametrize("curve", ["hilbert", "morton"])
def test_shader_reads_every_block_side(gl_ctx, curve):
    # Blocks of 1 texel (no walk) to 4096 (three four-level steps), quartered or not.
    rng = np.random.default_rng(12)
    img = _image(rng, 1100, 700, "mixed")
    for bits in (0, 1, 2, 3, 5, 8, 11, 12):
        assert _check_lookups(gl_ctx, img, curve, rng, bits=bits) == min(bits, 11)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), h=st.integers(1, 90), w=st.integers(1, 90),
       curve=st.sampled_from(["hilbert", "morton"]), k=st.integers(1, 5))
def test_shader_lookups_equal_cpu_hypothesis(gl_ctx, seed, h, w, curve, k):
    rng = np.random.default_rng(seed)
    img = rng.integers(0, k, (h, w)).astype(np.uint8)
    img[: h // 2, : w // 2] = k - 1
    _check_lookups(gl_ctx, img, curve, rng, n=500)


def test_lookup_refuses_bad_coordinates(gl_ctx):
    grid = PackedGrid(gl_ctx, pack(np.zeros((4, 4), np.uint8)))
    try:
        with pytest.raises(TerrathemeError, match="one of each per texel"):
            grid.lookup(np.arange(3), np.arange(2))
        with pytest.raises(TerrathemeError, match="32-bit"):
            grid.lookup(np.array([2**31]), np.array([0]))
        assert grid.lookup(np.zeros(0), np.zeros(0)).size == 0
    finally:
        grid.release()


STYLES = {
    "linear": RenderOptions(),
    "shaped": RenderOptions(boundary=BoundaryOptions()),
    "histogram": RenderOptions(blend=BlendMode.HISTOGRAM),
    "saddle-main": RenderOptions(saddle=SaddleRule.MAIN),
}


@pytest.mark.parametrize("curve", ["hilbert", "morton"])
@pytest.mark.parametrize("style", list(STYLES))
@pytest.mark.parametrize("cell", [(4, 4), (5, 3), (1, 1), (7, 2)])
def test_packed_render_equals_dense_and_cpu(renderer, curve, style, cell):
    rng = np.random.default_rng(cell[0] * 7 + cell[1])
    grid = rng.integers(0, 4, (23, 31)).astype(np.uint8)
    grid[:6, :9] = 2
    grid[10:12, 10:12] = [[0, 1], [1, 0]]  # saddles both ways
    assert set(np.unique(cell_splits(grid))) == {0, 1, 2}
    opts = STYLES[style]
    gpu_opts = GpuRenderOptions.from_render_options(opts, tile=37)  # many tiles
    cpu = render_cells(grid, THEMES, cell, options=opts)
    dense = renderer.render(grid, cell, options=gpu_opts)
    packed = renderer.render(pack(grid, curve=curve), cell, options=gpu_opts)
    np.testing.assert_array_equal(packed, dense)
    limit = 1 if style == "histogram" else 0
    assert np.abs(packed.astype(np.int16) - cpu).max() <= limit


def test_packed_render_with_colour_map_region_and_scale(renderer):
    rng = np.random.default_rng(3)
    grid = rng.integers(0, 5, (40, 33)).astype(np.uint8)
    cell = (6, 5)
    size = (32 * 6, 39 * 5)
    cmap = ColourMap(rng.integers(0, 256, (-(-size[1] // 8), -(-size[0] // 8), 3),
                                  dtype=np.uint8), 8)
    layer = pack(grid, curve="hilbert")
    region = (13, 7, 101, 77)
    cpu = render_cells(grid, THEMES, cell, region, colour_map=cmap)
    packed = renderer.render(layer, cell, region, colour_map=cmap,
                             options=GpuRenderOptions(tile=50))
    np.testing.assert_array_equal(packed, cpu)
    # The filtered path (an overview) reads the same grid blocks.
    dense = renderer.render(grid, cell, scale=0.4)
    np.testing.assert_array_equal(renderer.render(layer, cell, scale=0.4), dense)


def test_packed_grid_errors(renderer):
    grid = np.zeros((5, 6), np.uint8)
    layer = pack(grid)
    with pytest.raises(TerrathemeError, match="cell size"):
        renderer.render(layer)
    with pytest.raises(TerrathemeError, match="uses theme 7"):
        renderer.render(pack(np.full((3, 3), 7, np.uint8)), (2, 2))
    with pytest.raises(TerrathemeError, match="at least 2 x 2"):
        renderer.render(pack(np.zeros((1, 9), np.uint8)), (2, 2))
    with pytest.raises(TerrathemeError, match="colour layer"):
        renderer.render(pack(np.zeros((3, 3, 3), np.uint8)), (2, 2))
    # A one-channel layer of 16-bit values (a grey image), not theme indices.
    with pytest.raises(TerrathemeError, match="uint16 values through a palette"):
        renderer.render(pack(np.full((3, 3), 300, np.uint16)), (2, 2))
    with pytest.raises(TerrathemeError, match="outside"):
        renderer.render(layer, (4, 4), region=(0, 0, 50, 4))
    with pytest.raises(TerrathemeError, match="tiled packed layer"):
        renderer.render(pack(np.zeros((300, 200), np.uint8), tile_bits=7), (2, 2))


def _project_and_layer(tmp_path):
    """A copy of the airfield sample and its grid packed beside it (convert's default name)."""
    import shutil
    from pathlib import Path

    from terratheme.core.model.project import load_project

    repo = Path(__file__).resolve().parents[1]
    project = tmp_path / "airfield.ttproj"
    shutil.copy(repo / "sample_maps" / "airfield.ttproj", project)
    grid = load_project(project).grid.indices
    pack(grid, curve="morton").save(tmp_path / "airfield.ttpack")
    return project, grid


def test_cli_render_gpu_from_the_packed_layer(renderer, tmp_path, capsys):
    from terratheme.app.cli import main
    from terratheme.core.io.images import read_image

    project, _ = _project_and_layer(tmp_path)
    args = ["--region", "40,24,150,90"]
    assert main(["render", str(project), str(tmp_path / "p.png"), "--gpu", "--packed",
                 *args]) == 0
    assert "GPU from the packed layer" in capsys.readouterr().out
    assert main(["render", str(project), str(tmp_path / "d.png"), "--gpu", *args]) == 0
    assert main(["render", str(project), str(tmp_path / "c.png"), *args]) == 0
    packed, dense = read_image(tmp_path / "p.png"), read_image(tmp_path / "d.png")
    np.testing.assert_array_equal(packed, dense)
    assert np.abs(packed.astype(np.int16) - read_image(tmp_path / "c.png")).max() <= 1


def test_cli_render_packed_errors(renderer, tmp_path, capsys):
    from terratheme.app.cli import main

    project, grid = _project_and_layer(tmp_path)
    out = str(tmp_path / "x.png")
    assert main(["render", str(project), out, "--packed"]) == 2
    assert "add --gpu" in capsys.readouterr().err
    assert main(["render", str(project), out, "--gpu", "--packed", str(tmp_path / "no")]) == 2
    assert "no such file" in capsys.readouterr().err
    pack(grid[:-1]).save(tmp_path / "small.ttpack")
    assert main(["render", str(project), out, "--gpu", "--packed",
                 str(tmp_path / "small.ttpack")]) == 2
    assert "vertices" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()
