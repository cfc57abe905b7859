"""Flying a camera over the ground plane, and its OpenGL clip matrix (no Qt).

:class:`Flight` is a fly-over camera in :class:`core.perspective.Camera`'s conventions,
driven by key, mouse and wheel input; its speed follows the height, so the ground flows
past at one angular rate at any altitude. :func:`clip_matrix` takes a ground point to
the pixel eq. 1 maps it to, for a mesh displaced by a height map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.perspective.mapping import Camera

#: pitch limits of a flight, degrees below the horizontal (90 straight down)
MIN_PITCH, MAX_PITCH = -45.0, 90.0
#: lowest flying height, texels above the ground under the camera
MIN_CLEARANCE = 0.5


@dataclass(frozen=True)
class FlightControls:
    """How fast a flight answers its input: ``speed`` in camera heights per second (four
    times with ``fast``), ``climb`` as a factor of the height per second (the same time per
    doubling at any height), ``turn`` degrees per second from the arrow keys, ``look``
    degrees per pixel of mouse drag.
    """

    speed: float = 1.0
    climb: float = 1.0
    turn: float = 60.0
    look: float = 0.25


@dataclass(frozen=True)
class FlightInput:
    """What is held down during a time step, each axis in -1..1: ``forward``, ``right``, ``up``
    (along the heading, across, vertically), ``yaw``, ``pitch`` (turn right, pitch down);
    ``fast`` moves four times faster.
    """

    forward: float = 0.0
    right: float = 0.0
    up: float = 0.0
    yaw: float = 0.0
    pitch: float = 0.0
    fast: bool = False

    @property
    def idle(self) -> bool:
        """True when nothing moves the camera."""
        return not any((self.forward, self.right, self.up, self.yaw, self.pitch))


@dataclass(frozen=True)
class Flight:
    """A fly-over camera: ``x, y`` over the plane and ``height`` above it (> 0) in texels,
    ``yaw``, ``pitch`` (kept in ``[MIN_PITCH, MAX_PITCH]``) and ``fov`` in degrees, as
    :class:`core.perspective.Camera`.
    """

    x: float
    y: float
    height: float
    yaw: float = 0.0
    pitch: float = 20.0
    fov: float = 60.0

    def __post_init__(self) -> None:
        self.camera()  # the same checks as the perspective preview's camera

    def camera(self) -> Camera:
        """The perspective preview's camera for this flight."""
        return Camera(height=self.height, pitch=self.pitch, yaw=self.yaw, fov=self.fov,
                      x=self.x, y=self.y)

    def turned(self, yaw: float, pitch: float) -> Flight:
        """Turned by ``yaw`` degrees clockwise and pitched ``pitch`` degrees further down."""
        new_yaw = (self.yaw + yaw + 180.0) % 360.0 - 180.0
        new_pitch = min(MAX_PITCH, max(MIN_PITCH, self.pitch + pitch))
        return replace(self, yaw=new_yaw, pitch=new_pitch)

    def moved(self, forward: float, right: float, up: float = 0.0,
              ground: float = 0.0) -> Flight:
        """Moved ``forward`` texels along the heading, ``right`` across it, ``up`` vertically.

        The heading is horizontal (pitch does not tilt the motion); the height
        stays at least :data:`MIN_CLEARANCE` above ``ground``, the terrain's
        height under the new position.
        """
        s, c = math.sin(math.radians(self.yaw)), math.cos(math.radians(self.yaw))
        # yaw 0 looks toward -V; right is +U there (core.perspective.camera_mapping)
        x = self.x + forward * s + right * c
        y = self.y - forward * c + right * s
        height = max(self.height + up, ground + MIN_CLEARANCE)
        return replace(self, x=x, y=y, height=height)

    def step(self, held: FlightInput, seconds: float, controls: FlightControls = FlightControls(),
             ground: float = 0.0) -> Flight:
        """The flight after ``seconds`` of ``held`` input."""
        boost = 4.0 if held.fast else 1.0
        turned = self.turned(held.yaw * controls.turn * seconds,
                             held.pitch * controls.turn * seconds)
        reach = turned.height * controls.speed * boost * seconds
        climb = turned.height * (math.exp(held.up * controls.climb * boost * seconds) - 1.0)
        return turned.moved(held.forward * reach, held.right * reach, climb, ground)

    def looked(self, dx: float, dy: float, controls: FlightControls = FlightControls()) -> Flight:
        """Turned by a mouse drag of ``(dx, dy)`` pixels (right: turn right; down: look down)."""
        return self.turned(dx * controls.look, dy * controls.look)

    def zoomed(self, steps: float, ground: float = 0.0) -> Flight:
        """Height changed by wheel ``steps`` (each step 15% closer to the ground)."""
        height = max(self.height * 0.85 ** steps, ground + MIN_CLEARANCE)
        return replace(self, height=height)


def camera_axes(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``forward, right, down`` unit vectors in ground coordinates ``(U, V, up)``.

    The basis of :func:`core.perspective.camera_mapping`: pixel ``(x, y)`` looks
    along ``f * forward + (x - w/2) * right + (y - h/2) * down``.
    """
    th, ps = math.radians(camera.pitch), math.radians(camera.yaw)
    ct, st, cp, sp = math.cos(th), math.sin(th), math.cos(ps), math.sin(ps)
    forward = np.array([ct * sp, -ct * cp, -st])
    right = np.array([cp, sp, 0.0])
    down = np.array([-st * sp, st * cp, -ct])
    return forward, right, down


def clip_matrix(camera: Camera, size: tuple[int, int], texture_size: tuple[int, int],
                near: float, far: float, *, flip_y: bool = False) -> np.ndarray:
    """The camera as a (4, 4) row-major OpenGL clip matrix over ground points ``(U, V, height,
    1)`` (``clip = M @ point``; upload its transpose as a GLSL ``mat4``).

    ``camera``'s default position is the ``texture_size`` (W, H) texture's centre, as in
    eq. 1; ``size`` (w, h) pixels; ``near``, ``far`` the depth range in texels. ``flip_y``
    False puts the frame's top row in window row 0 (read back into an image), True
    draws it upright on a display.
    """
    if not 0.0 < near < far:
        raise TerrathemeError(f"depth range must satisfy 0 < near < far, got {near}, {far}")
    w, h = size
    f = (w / 2.0) / math.tan(math.radians(camera.fov) / 2.0)
    x0 = texture_size[0] / 2.0 if camera.x is None else float(camera.x)
    y0 = texture_size[1] / 2.0 if camera.y is None else float(camera.y)
    eye = np.array([x0, y0, float(camera.height)])
    forward, right, down = camera_axes(camera)
    sign = -1.0 if flip_y else 1.0
    depth_a = (far + near) / (far - near)
    depth_b = -2.0 * far * near / (far - near)
    # Clip rows: x and y from the ray's right and down parts over its forward part (eq. 1),
    # z the usual perspective depth, w the distance along the view axis.
    rows = [2.0 * f / w * right, sign * 2.0 * f / h * down, depth_a * forward, forward]
    out = np.zeros((4, 4))
    for i, axis in enumerate(rows):
        out[i, :3] = axis
        out[i, 3] = -axis @ eye
    out[2, 3] += depth_b
    return out
