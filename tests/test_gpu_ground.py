"""The ground plane on the GPU (core.gpu.ground): mapping, filtering, height maps, live edits.

Known answers where the view makes them exact (a camera straight down at one
texel per pixel shows the render itself; a constant height map is a lower
camera), and the CPU preview's supersampled reference on the same camera for
the filtering, measured against the CPU's trilinear filter in the same test.
Every test skips with the reason when no OpenGL 3.3 context can be made.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.gpu import (
    Anisotropy,
    GroundOptions,
    GroundView,
    render_perspective_gpu,
)
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.perspective import (
    Camera,
    FilterOptions,
    Method,
    PreparedTexture,
    camera_mapping,
)
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.renderer import RenderOptions, render_cells
from terratheme.core.themes.library import Theme, ThemeLibrary

SHAPED = RenderOptions(boundary=BoundaryOptions())
#: the shader's own probes, so results do not depend on the driver's anisotropic filter
PROBES = GroundOptions(anisotropy=Anisotropy.SHADER)


def _themes(seed: int, k: int = 3, size: int = 32) -> list[np.ndarray]:
    # Smooth-ish themes (a few octaves of noise): filtering errors stay measurable.
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(k):
        base = rng.integers(40, 220, 3)
        detail = rng.normal(0, 25, (size // 4, size // 4, 3))
        up = np.kron(detail, np.ones((4, 4, 1)))
        out.append(np.clip(base + up, 0, 255).astype(np.uint8))
    return out


def _grid(seed: int, shape=(17, 21), k: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    coarse = rng.integers(0, k, (shape[0] // 2 + 1, shape[1] // 2 + 1))
    return np.kron(coarse, np.ones((2, 2), int))[: shape[0], : shape[1]].astype(np.uint8)


def _top_down(texture_size, x0, y0, w, h) -> Camera:
    """A camera straight down whose pixel (px, py) is centred on texel (x0 + px, y0 + py)."""
    f = (w / 2.0) / math.tan(math.radians(60.0) / 2.0)
    return Camera(height=f, pitch=90.0, yaw=0.0, fov=60.0, x=x0 + w / 2.0, y=y0 + h / 2.0)


@pytest.mark.parametrize("options", [PROBES, GroundOptions(base_map=0)],
                         ids=["base map", "per-pixel blend"])
@pytest.mark.parametrize("style", [RenderOptions(), SHAPED])
def test_straight_down_at_one_texel_per_pixel_is_the_render(gl_ctx, style, options):
    themes, grid = _themes(1), _grid(2)
    cell = (8, 6)
    cmap = ColourMap(np.random.default_rng(3).integers(70, 200, (12, 20, 3), dtype=np.uint8), 8)
    view = GroundView(grid, themes, cell, style=style, colour_map=cmap, context=gl_ctx,
                      options=options)
    try:
        # A window crossing the texture's right and bottom edges: the plane repeats there.
        w, h = 64, 40
        x0, y0 = view.texture_size[0] - 40, view.texture_size[1] - 25
        frame = view.render(_top_down(view.texture_size, x0, y0, w, h), (w, h))
        full = render_cells(grid, themes, cell, options=style, colour_map=cmap)
        want = np.roll(full, (-y0, -x0), axis=(0, 1))[:h, :w]
        diff = np.abs(frame.astype(np.int16) - want)
        # The filtered path: weights in 1/4096, the colour map read by the hardware.
        assert diff.max() <= 3 and diff.mean() < 0.6
    finally:
        view.release()


def test_the_sky_is_above_the_horizon_and_a_mapping_draws_as_its_camera(gl_ctx):
    view = GroundView(_grid(4), _themes(4), (8, 8), context=gl_ctx,
                      options=GroundOptions(sky=(0.0, 0.5, 1.0)))
    try:
        camera = Camera(height=20.0, pitch=0.0, yaw=30.0)
        frame = view.render(camera, (80, 60))
        assert (frame[:29] == (0, 128, 255)).all()
        assert (frame[31:] != (0, 128, 255)).any(axis=2).all()
        mapped = view.render(camera_mapping(camera, (80, 60), view.texture_size), (80, 60))
        assert np.array_equal(mapped, frame)
    finally:
        view.release()


@pytest.mark.parametrize("pitch", [6.0, 20.0])
def test_grazing_frames_are_closer_to_the_reference_than_trilinear(gl_ctx, pitch):
    themes, grid = _themes(5), _grid(6, (33, 33))
    cell = (8, 8)
    texture = render_cells(grid, themes, cell)
    camera = Camera(height=12.0, pitch=pitch, yaw=25.0, x=100.0, y=180.0)
    size = (160, 96)
    reference = PreparedTexture(texture, FilterOptions(method=Method.REFERENCE)).render(
        camera, size).image

    def psnr(image):
        return -10 * math.log10(float(((image - reference) ** 2).mean()))

    trilinear = PreparedTexture(texture, FilterOptions(method=Method.TRILINEAR)).render(
        camera, size).image
    view = GroundView(grid, themes, cell, options=PROBES, context=gl_ctx)
    try:
        gpu = view.render(camera, size).astype(np.float32) / 255
    finally:
        view.release()
    assert psnr(gpu) >= psnr(trilinear) + 2.0  # measured +3.3 and +7.9 dB


def test_a_constant_height_map_is_a_lower_camera(gl_ctx):
    themes, grid = _themes(7), _grid(8)
    view = GroundView(grid, themes, (8, 8), options=PROBES, context=gl_ctx)
    try:
        low = Camera(height=30.0, pitch=70.0, yaw=10.0, x=80.0, y=64.0)
        flat = view.render(low, (96, 64))
        view.set_height_map(np.full((5, 7), 0.5, np.float32), 40.0)
        assert view.ground_height(80.0, 64.0) == pytest.approx(20.0)
        raised = view.render(Camera(height=50.0, pitch=70.0, yaw=10.0, x=80.0, y=64.0),
                             (96, 64))
        # The same picture (mesh interpolation against eq. 1 per pixel: within a level or two).
        diff = np.abs(raised.astype(np.int16) - flat)
        assert diff.mean() < 1.0 and np.percentile(diff, 99) <= 8
        # A slope: the near side rises toward the camera, so the frame changes.
        view.set_height_map(np.tile(np.linspace(0, 255, 16).astype(np.uint8), (16, 1)), 40.0)
        assert view.ground_height(view.texture_size[0], 0.0) == pytest.approx(40.0)
        sloped = view.render(Camera(height=50.0, pitch=70.0, yaw=10.0, x=80.0, y=64.0),
                             (96, 64))
        assert np.abs(sloped.astype(np.int16) - raised).mean() > 3
        view.set_height_map(None)
        assert np.array_equal(view.render(low, (96, 64)), flat)
    finally:
        view.release()


def test_edits_upload_only_the_dirty_cells(gl_ctx):
    themes = _themes(9)
    indices = _grid(10, (33, 41))
    view = GroundView(indices, themes, (6, 6), style=SHAPED, options=PROBES, context=gl_ctx)
    try:
        camera = Camera(height=40.0, pitch=35.0, yaw=-20.0, x=120.0, y=100.0)
        view.render(camera, (96, 64))
        assert view.uploaded == []
        # Paint a 3 x 4 vertex box in place, as the editor's document does, and say so.
        indices[12:15, 20:24] = (indices[12:15, 20:24] + 1) % 3
        view.mark_dirty(slice(12, 15), slice(20, 24))
        edited = view.render(camera, (96, 64))
        # Cells 11..14 x 19..23 touch the box; one more ring for the saddle rule.
        assert view.uploaded == [(18, 10, 7, 6)]
        fresh = GroundView(indices.copy(), themes, (6, 6), style=SHAPED, options=PROBES,
                           context=gl_ctx)
        try:
            assert np.array_equal(edited, fresh.render(camera, (96, 64)))
        finally:
            fresh.release()
    finally:
        view.release()


def test_render_perspective_gpu_draws_a_project_in_its_style(gl_ctx):
    themes, grid = _themes(11), _grid(12)
    library = ThemeLibrary([Theme(f"t{k}", (60 * k, 90, 120), t) for k, t in enumerate(themes)])
    cmap = ColourMap(np.full((13, 16, 3), 64, np.uint8), 10)
    project = ThematicTexture(IndexGrid(grid, (8, 8)), library, colour_map=cmap,
                              metadata={"render": {"boundary": {"width": 2.0}}})
    camera = Camera(height=25.0, pitch=30.0, yaw=45.0)
    frame = render_perspective_gpu(project, camera, (80, 48), options=PROBES)
    assert frame.shape == (48, 80, 3) and frame.dtype == np.uint8
    # The colour map halves every texel: the frame is about half the neutral one's.
    plain = ThematicTexture(IndexGrid(grid, (8, 8)), library,
                            metadata={"render": {"boundary": {"width": 2.0}}})
    neutral = render_perspective_gpu(plain, camera, (80, 48), options=PROBES)
    ground = frame[20:]
    assert np.abs(ground.astype(np.float64) - neutral[20:] / 2).mean() < 1.0


def test_bad_views_and_options_are_refused(gl_ctx):
    view = GroundView(_grid(13), _themes(13), (8, 8), context=gl_ctx)
    try:
        camera = Camera(height=10.0, pitch=20.0)
        with pytest.raises(TerrathemeError, match="frame size"):
            view.render(camera, (0, 10))
        with pytest.raises(TerrathemeError, match="PlaneMapping or a Camera"):
            view.render("north", (10, 10))
        view.set_height_map(np.zeros((4, 4)), 1.0)
        with pytest.raises(TerrathemeError, match="height map needs a Camera"):
            view.render(camera_mapping(camera, (10, 10), view.texture_size), (10, 10))
        for bad, match in ((np.full((3, 3), np.nan), "NaN"), (np.zeros((0, 4)), "non-empty"),
                           (np.zeros((3, 3), bool), "numbers")):
            with pytest.raises(TerrathemeError, match=match):
                view.set_height_map(bad, 1.0)
        with pytest.raises(TerrathemeError, match="height scale"):
            view.set_height_map(np.zeros((3, 3)), -1.0)
    finally:
        view.release()
    with pytest.raises(TerrathemeError, match="max_supersample"):
        GroundOptions(max_supersample=0)
    with pytest.raises(TerrathemeError, match="sky"):
        GroundOptions(sky=(2.0, 0.0, 0.0))
    with pytest.raises(TerrathemeError, match="base_map"):
        GroundOptions(base_map=-1)
    with pytest.raises(TerrathemeError, match="theme"):
        GroundView(np.full((3, 3), 9), _themes(1), (4, 4), context=gl_ctx)
    with pytest.raises(TerrathemeError, match="colour map is"):
        GroundView(_grid(1), _themes(1), (4, 4), context=gl_ctx,
                   colour_map=ColourMap(np.zeros((2, 2, 3), np.uint8), 4))


def test_a_large_texture_gets_a_reduced_base_map(gl_ctx):
    # 256 x 192 texels with base maps of at most 64 a side: 4 texels per base texel.
    themes, grid = _themes(15), _grid(16, (25, 33))
    view = GroundView(grid, themes, (8, 8), options=GroundOptions(base_map=64), context=gl_ctx)
    try:
        assert view.base.step == 4 and view.base.size == (64, 48)
        far = Camera(height=30.0, pitch=4.0, yaw=10.0)
        frame = view.render(far, (96, 64))
        whole = GroundView(grid, themes, (8, 8), options=GroundOptions(base_map=0),
                           context=gl_ctx)
        try:
            # The far field from the reduced render, the rest per pixel: close to no base map.
            assert np.abs(frame.astype(np.int16) - whole.render(far, (96, 64))).mean() < 6
        finally:
            whole.release()
    finally:
        view.release()


def test_a_reduced_frame_is_the_small_frame_stretched(gl_ctx):
    # A moving camera draws half the pixels a side, stretched bilinearly over the frame.
    import cv2

    view = GroundView(_grid(14), _themes(14), (8, 8), options=PROBES, context=gl_ctx)
    try:
        camera = Camera(height=20.0, pitch=25.0, yaw=15.0)
        small = view.render(camera, (48, 32))
        stretched = view.render(camera, (96, 64), scale=0.5)
        want = cv2.resize(small, (96, 64), interpolation=cv2.INTER_LINEAR)
        assert np.abs(stretched.astype(np.int16) - want).max() <= 2
        full = view.render(camera, (96, 64))
        assert np.abs(stretched.astype(np.int16) - full).mean() < 12
    finally:
        view.release()


def test_cli_perspective_gpu_renders_a_project_frame(gl_ctx, tmp_path, capsys):
    from terratheme.app.cli import main
    from terratheme.core.io.images import read_image

    out = tmp_path / "frame.png"
    assert main(["perspective", "sample_maps/coastline.ttproj", str(out), "--gpu",
                 "--size", "160x90"]) == 0
    frame = read_image(out)
    assert frame.shape == (90, 160, 3) and frame.std() > 5
    assert "on the GPU" in capsys.readouterr().out
    assert main(["perspective", "sample_maps/coastline.png", str(tmp_path / "x.png"),
                 "--gpu"]) == 2
    assert "--gpu renders projects" in capsys.readouterr().err
