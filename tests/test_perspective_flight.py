"""The fly-over camera (core.perspective.flight): motion, limits and clip matrix, no GPU."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.perspective import Camera, camera_mapping
from terratheme.core.perspective.flight import (
    MAX_PITCH,
    MIN_CLEARANCE,
    MIN_PITCH,
    Flight,
    FlightControls,
    FlightInput,
    camera_axes,
    clip_matrix,
)


def test_forward_follows_the_heading_and_right_is_clockwise():
    # yaw 0 looks north (-V); yaw 90 looks east (+U), as core.perspective's camera.
    north = Flight(100.0, 100.0, 10.0, yaw=0.0)
    assert north.moved(5.0, 0.0).x == pytest.approx(100.0)
    assert north.moved(5.0, 0.0).y == pytest.approx(95.0)
    assert north.moved(0.0, 3.0).x == pytest.approx(103.0)
    east = Flight(100.0, 100.0, 10.0, yaw=90.0)
    assert (east.moved(5.0, 0.0).x, east.moved(5.0, 0.0).y) == pytest.approx((105.0, 100.0))
    assert (east.moved(0.0, 3.0).x, east.moved(0.0, 3.0).y) == pytest.approx((100.0, 103.0))


@settings(max_examples=100, deadline=None)
@given(yaw=st.floats(-180, 180), pitch=st.floats(MIN_PITCH, MAX_PITCH))
def test_moving_forward_goes_where_the_camera_looks(yaw, pitch):
    # The horizontal part of the camera's forward axis is the direction of travel.
    flight = Flight(0.0, 0.0, 10.0, yaw=yaw, pitch=min(pitch, 89.0))
    forward = camera_axes(flight.camera())[0]
    moved = flight.moved(1.0, 0.0)
    step = np.array([moved.x - flight.x, moved.y - flight.y])
    heading = forward[:2] / np.linalg.norm(forward[:2])
    assert np.allclose(step, heading, atol=1e-9)


def test_turning_wraps_yaw_and_clamps_pitch():
    f = Flight(0.0, 0.0, 5.0, yaw=170.0, pitch=80.0).turned(20.0, 30.0)
    assert f.yaw == pytest.approx(-170.0) and f.pitch == MAX_PITCH
    assert Flight(0.0, 0.0, 5.0, pitch=-40.0).turned(0.0, -30.0).pitch == MIN_PITCH
    assert Flight(0.0, 0.0, 5.0).looked(40.0, 20.0) == Flight(0.0, 0.0, 5.0).turned(10.0, 5.0)


def test_speed_follows_the_height():
    # The same input covers ten times the ground at ten times the height.
    held = FlightInput(forward=1.0)
    low = Flight(0.0, 0.0, 10.0).step(held, 0.5)
    high = Flight(0.0, 0.0, 100.0).step(held, 0.5)
    assert -low.y == pytest.approx(5.0) and -high.y == pytest.approx(50.0)
    fast = Flight(0.0, 0.0, 10.0).step(FlightInput(forward=1.0, fast=True), 0.5)
    assert -fast.y == pytest.approx(20.0)
    # Climbing doubles the height in ln 2 seconds at any height (exponential).
    up = FlightInput(up=1.0)
    assert Flight(0.0, 0.0, 3.0).step(up, math.log(2)).height == pytest.approx(6.0)
    assert Flight(0.0, 0.0, 300.0).step(up, math.log(2)).height == pytest.approx(600.0)
    turn = Flight(0.0, 0.0, 3.0, yaw=0.0).step(FlightInput(yaw=1.0), 0.5,
                                               FlightControls(turn=60.0))
    assert turn.yaw == pytest.approx(30.0) and FlightInput().idle and not held.idle


def test_the_camera_never_sinks_below_the_ground():
    f = Flight(0.0, 0.0, 2.0)
    assert f.moved(0.0, 0.0, -10.0).height == MIN_CLEARANCE
    assert f.moved(0.0, 0.0, 0.0, ground=7.0).height == 7.0 + MIN_CLEARANCE
    assert f.zoomed(100.0).height == MIN_CLEARANCE
    assert f.zoomed(-1.0).height == pytest.approx(2.0 / 0.85)
    assert f.step(FlightInput(up=-1.0), 100.0, ground=1.0).height == 1.0 + MIN_CLEARANCE


def test_a_flight_is_a_valid_perspective_camera():
    cam = Flight(320.0, 240.0, 40.0, 0.0, 20.0).camera()
    assert isinstance(cam, Camera) and (cam.x, cam.y, cam.pitch) == (320.0, 240.0, 20.0)
    with pytest.raises(TerrathemeError, match="height must be > 0"):
        Flight(0.0, 0.0, 0.0)
    with pytest.raises(TerrathemeError, match="fov"):
        Flight(0.0, 0.0, 1.0, fov=0.0)


@settings(max_examples=60, deadline=None)
@given(height=st.floats(1.0, 500.0), pitch=st.floats(1.0, 89.0), yaw=st.floats(-180, 180),
       fov=st.floats(20.0, 120.0), x=st.floats(-100, 1100), y=st.floats(-100, 900),
       flip=st.booleans())
def test_clip_matrix_puts_ground_points_on_the_pixels_eq1_maps_to_them(height, pitch, yaw, fov,
                                                                       x, y, flip):
    size, texture = (320, 200), (1000, 800)
    camera = Camera(height=height, pitch=pitch, yaw=yaw, fov=fov, x=x, y=y)
    mapping = camera_mapping(camera, size, texture)
    # Pixel centres below the horizon, their ground points by eq. 1, back through the matrix.
    px, py = np.meshgrid(np.arange(0, 320, 37) + 0.5, np.arange(0, 200, 23) + 0.5)
    u, v, z = mapping.evaluate(px.ravel(), py.ravel())
    ok = z > 1e-3 * np.abs(z).max()
    if not ok.any():
        return
    near, far = 0.01, 1e7
    clip = clip_matrix(camera, size, texture, near, far, flip_y=flip)
    points = np.stack([u[ok], v[ok], np.zeros(ok.sum()), np.ones(ok.sum())])
    c = clip @ points
    ndc = c[:3] / c[3]
    sx = (ndc[0] + 1) / 2 * size[0]
    sy = (ndc[1] + 1) / 2 * size[1]
    if flip:
        sy = size[1] - sy
    assert np.allclose(sx, px.ravel()[ok], atol=1e-4 * size[0])
    assert np.allclose(sy, py.ravel()[ok], atol=1e-4 * size[1])
    # Ground points in front of the camera: depth in range, w the distance along the view axis.
    assert (c[3] > 0).all() and (np.abs(ndc[2]) <= 1 + 1e-9).all()


def test_clip_matrix_depth_maps_near_and_far_to_minus_one_and_one():
    camera = Camera(height=10.0, pitch=90.0, x=0.0, y=0.0)
    clip = clip_matrix(camera, (100, 100), (10, 10), 2.0, 8.0)
    for depth, want in ((2.0, -1.0), (8.0, 1.0)):
        c = clip @ np.array([0.0, 0.0, 10.0 - depth, 1.0])  # straight below the camera
        assert c[3] == pytest.approx(depth) and c[2] / c[3] == pytest.approx(want)
    with pytest.raises(TerrathemeError, match="near < far"):
        clip_matrix(camera, (100, 100), (10, 10), 5.0, 1.0)
