"""Issues 16 and 18: the default low-angle view, and a project's texture at the
detail a frame needs (core/perspective/mapping.py, project_view.py)."""

from __future__ import annotations

import numpy as np
import pytest
import terratheme.core.perspective.project_view as project_view
from terratheme.core.errors import TerrathemeError
from terratheme.core.perspective import Camera, PlaneMapping, PreparedTexture, camera_mapping
from terratheme.core.perspective.mapping import overview_camera, scaled_view
from terratheme.core.perspective.project_view import (
    finest_footprint,
    project_texture,
    texture_scale,
)


@pytest.mark.parametrize("size", [(256, 256), (1536, 1152), (4096, 512), (64, 2048)])
def test_overview_camera_sees_the_whole_texture_at_a_low_angle(size):
    w, h = size
    cam = overview_camera(size)
    assert 5 <= cam.pitch <= 20
    m = camera_mapping(cam, (640, 360), size)
    # the frame's centre is the texture's centre, its bottom row inside the texture,
    # its top row sky
    u, v, z = m.evaluate(np.array([320.0, 320.0, 320.0]), np.array([180.0, 359.5, 0.5]))
    np.testing.assert_allclose([u[0], v[0]], [w / 2, h / 2], rtol=1e-6, atol=1e-6)
    assert 0 < u[1] < w and 0 < v[1] < h and z[2] <= 0
    # the far corners are in the frame: screen = inverse of eq. 1's matrix
    inv = np.linalg.inv(m.coefficients())
    far = [(0, 0), (w, 0)] if h >= w else [(w, 0), (w, h)]
    for uu, vv in far:
        x, y, s = inv @ np.array([uu, vv, 1.0])
        assert s > 0 and 0 <= x / s <= 640 and 0 <= y / s <= 360


def test_finest_footprint_of_a_uniform_view():
    assert finest_footprint(PlaneMapping(4, 0, 0, 0, 3, 0, 0, 0, 1), (8, 8)) == pytest.approx(3)
    assert finest_footprint(PlaneMapping(0, 0, 0, 0, 0, 0, 0, 0, -1), (8, 8)) == np.inf


@pytest.mark.parametrize("coefs, size, max_side, want", [
    ((4, 0, 0, 0, 4, 0, 0, 0, 1), (1024, 1024), 4096, 0.25),  # 4 texels per pixel
    ((5, 0, 0, 0, 7, 0, 0, 0, 1), (1024, 1024), 4096, 0.25),  # 5 to 7: still a quarter
    ((1, 0, 0, 0, 1, 0, 0, 0, 1), (1024, 1024), 4096, 1.0),  # one to one
    ((0.2, 0, 0, 0, 0.2, 0, 0, 0, 1), (1024, 1024), 256, 0.25),  # magnified, capped
    ((64, 0, 0, 0, 64, 0, 0, 0, 1), (32, 16), 4096, 1 / 32),  # no smaller than a texel
])
def test_texture_scale(coefs, size, max_side, want):
    assert texture_scale(PlaneMapping(*coefs), (16, 16), size, max_side) == want


def test_texture_scale_refuses_a_zero_side():
    with pytest.raises(TerrathemeError, match="at least 1"):
        texture_scale(PlaneMapping(1, 0, 0, 0, 1, 0, 0, 0, 1), (4, 4), (8, 8), 0)


def test_scaled_view_keeps_the_frame():
    tex = np.random.default_rng(0).random((64, 64, 3)).astype(np.float32)
    half = tex.reshape(32, 2, 32, 2, 3).mean(axis=(1, 3))
    cam = Camera(height=30, pitch=60, yaw=10, fov=50, x=31, y=33)
    a = camera_mapping(cam, (40, 30), (64, 64))
    b = camera_mapping(scaled_view(cam, 0.5, 0.5), (40, 30), (32, 32))
    pix = (np.array([3.5, 20.5]), np.array([25.5, 9.5]))
    ua, va, _ = a.evaluate(*pix)
    ub, vb, _ = b.evaluate(*pix)
    np.testing.assert_allclose(ub, 0.5 * ua, atol=1e-9)
    np.testing.assert_allclose(vb, 0.5 * va, atol=1e-9)
    assert PreparedTexture(half).render(scaled_view(cam, 0.5, 0.5), (40, 30)).image.shape == (
        30, 40, 3)


def _project():
    from terratheme.core.model.grid import IndexGrid
    from terratheme.core.model.project import ThematicTexture
    from terratheme.core.themes.library import ThemeLibrary, flat_theme

    rng = np.random.default_rng(3)
    lib = ThemeLibrary([flat_theme("field", (200, 180, 40)), flat_theme("water", (20, 60, 200)),
                        flat_theme("town", (120, 120, 120))])
    grid = IndexGrid(rng.integers(0, 3, (17, 17)).astype(np.uint8), (16, 16))
    return ThematicTexture(grid, lib)


def test_a_high_view_renders_the_project_reduced_never_at_full_resolution(monkeypatch):
    from terratheme.core.render.project import render_project

    project = _project()
    scales = []

    def recording(p, region=None, scale=1.0, **kw):
        scales.append(scale)
        return render_project(p, region, scale, **kw)

    monkeypatch.setattr(project_view, "render_project", recording)
    # straight down, about 8 texels per pixel
    cam = Camera(height=1100, pitch=90, fov=60)
    texture, view = project_texture(project, cam, (80, 60))
    assert scales == [0.125]
    assert texture.shape == (32, 32, 3)
    np.testing.assert_array_equal(texture, render_project(project, None, 0.125))
    full = render_project(project)
    a = PreparedTexture(full).render(cam, (80, 60)).image
    b = PreparedTexture(texture).render(view, (80, 60)).image
    assert np.sqrt(np.mean((a - b) ** 2)) < 0.02


def test_a_low_view_renders_the_project_at_full_resolution_within_the_bound():
    project = _project()
    cam = overview_camera(project.grid.texture_size)
    texture, _ = project_texture(project, cam, (64, 36))
    assert texture.shape == (256, 256, 3)
    small, _ = project_texture(project, cam, (64, 36), max_side=100)
    assert max(small.shape) <= 100
