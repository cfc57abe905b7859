"""Plane mapping of eq. 1 and the camera that produces it.

Conventions:

* screen pixel ``(px, py)`` covers ``[px, px+1) x [py, py+1)``, row 0 at the
  top; a pixel is sampled at its centre ``(px + 0.5, py + 0.5)``;
* ``U, V`` are in texels of the input texture: texel ``(i, j)`` covers
  ``[i, i+1) x [j, j+1)``, ``i`` the column, ``j`` the row from the top; the
  texture wraps;
* the ground plane is the texture plane, the camera is ``height`` texels above
  it; ``yaw = 0`` looks toward ``-V`` (up the image, "north"), yaw turns
  clockwise seen from above; ``pitch`` is the angle below the horizontal
  (90 = straight down); ``fov`` is the horizontal field of view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from terratheme.core.errors import TerrathemeError

#: derivatives are clipped to this many texels per pixel (past the horizon
#: they overflow; every filter treats this as "the whole texture")
MAX_DERIVATIVE = 1e12


@dataclass(frozen=True)
class PlaneMapping:
    """``U = (Au x + Bu y + Cu) / z``, ``V = (Av x + Bv y + Cv) / z``,
    ``z = Az x + Bz y + Cz`` (Kovalev & Tarasov, eq. 1).

    The nine coefficients are homogeneous: scaling all of them by a positive
    number gives the same mapping. Pixels with ``z <= 0`` are above the
    horizon.
    """

    Au: float
    Bu: float
    Cu: float
    Av: float
    Bv: float
    Cv: float
    Az: float
    Bz: float
    Cz: float

    def __post_init__(self) -> None:
        vals = self.coefficients()
        if not np.all(np.isfinite(vals)):
            raise TerrathemeError(f"plane mapping has non-finite coefficients: {vals.tolist()}")
        if self.Az == 0 and self.Bz == 0 and self.Cz == 0:
            raise TerrathemeError(
                "plane mapping is singular: Az = Bz = Cz = 0, so z = 0 at every pixel"
            )

    @classmethod
    def from_sequence(cls, values) -> PlaneMapping:
        """From nine numbers ``Au, Bu, Cu, Av, Bv, Cv, Az, Bz, Cz``."""
        vals = [float(v) for v in values]
        if len(vals) != 9:
            raise TerrathemeError(f"a plane mapping needs 9 coefficients, got {len(vals)}")
        return cls(*vals)

    def coefficients(self) -> np.ndarray:
        """``(3, 3) float64``: rows (U, V, z), columns (A, B, C)."""
        return np.array(
            [[self.Au, self.Bu, self.Cu], [self.Av, self.Bv, self.Cv],
             [self.Az, self.Bz, self.Cz]],
            dtype=np.float64,
        )

    def scaled(self, su: float, sv: float) -> PlaneMapping:
        """The same plane with ``U`` multiplied by ``su`` and ``V`` by ``sv``
        (used when the texture is resampled to a power of two)."""
        return PlaneMapping(
            self.Au * su, self.Bu * su, self.Cu * su,
            self.Av * sv, self.Bv * sv, self.Cv * sv,
            self.Az, self.Bz, self.Cz,
        )

    def evaluate(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, ...]:
        """Eq. 1 at screen points ``x, y`` (centre ``px + 0.5``): U, V (NaN where z <= 0), z."""
        # Finite coefficients far apart (1e308, 1e-308) overflow to inf: a point far off
        # the texture, not a warning on stderr.
        with np.errstate(over="ignore", invalid="ignore"):
            z = self.Az * x + self.Bz * y + self.Cz
            ok = z > 0
            zs = np.where(ok, z, 1.0)
            u = np.where(ok, (self.Au * x + self.Bu * y + self.Cu) / zs, np.nan)
            v = np.where(ok, (self.Av * x + self.Bv * y + self.Cv) / zs, np.nan)
        return u, v, z

    def derivatives(
        self, u: np.ndarray, v: np.ndarray, z: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Eq. 2: ``dudx, dvdx, dudy, dvdy``, ``dU/dx = (Au - Az U)/z`` etc., clipped to
        ``+-MAX_DERIVATIVE``, 0 where ``z <= 0``.
        """
        ok = z > 0
        zs = np.where(ok, z, 1.0)
        uu = np.where(ok, u, 0.0)
        vv = np.where(ok, v, 0.0)
        out = []
        with np.errstate(over="ignore", invalid="ignore"):  # inf U, V (evaluate)
            for num in (self.Au - self.Az * uu, self.Av - self.Az * vv,
                        self.Bu - self.Bz * uu, self.Bv - self.Bz * vv):
                d = np.where(ok, num / zs, 0.0)
                out.append(np.clip(np.nan_to_num(d, nan=0.0), -MAX_DERIVATIVE, MAX_DERIVATIVE))
        return out[0], out[1], out[2], out[3]

    def pixel_grid(self, size: tuple[int, int]) -> tuple[np.ndarray, ...]:
        """Eqs. 1-2 at the pixel centres of a (w, h) frame: u, v, z, dudx, dvdx, dudy, dvdy."""
        w, h = size
        x = np.arange(w, dtype=np.float64) + 0.5
        y = np.arange(h, dtype=np.float64) + 0.5
        xx, yy = np.meshgrid(x, y)
        u, v, z = self.evaluate(xx, yy)
        return (u, v, z, *self.derivatives(u, v, z))


@dataclass(frozen=True)
class Camera:
    """A pinhole camera ``height`` texels (> 0) above the texture plane.

    ``pitch``: degrees below the horizontal in [-90, 90] (90 = straight down);
    ``yaw``: heading in degrees clockwise from ``-V`` (north); ``fov``: horizontal
    field of view in degrees in (0, 170]; ``x, y``: position in texels (None = the
    texture's centre).
    """

    height: float
    pitch: float
    yaw: float = 0.0
    fov: float = 60.0
    x: float | None = None
    y: float | None = None

    def __post_init__(self) -> None:
        vals = [self.height, self.pitch, self.yaw, self.fov]
        vals += [c for c in (self.x, self.y) if c is not None]
        if not all(math.isfinite(float(c)) for c in vals):
            raise TerrathemeError(f"camera values must be finite numbers, got {vals}")
        if self.height <= 0:
            raise TerrathemeError(f"camera height must be > 0 texels, got {self.height}")
        if not -90 <= self.pitch <= 90:
            raise TerrathemeError(f"camera pitch must be in [-90, 90] degrees, got {self.pitch}")
        if not 0 < self.fov <= 170:
            raise TerrathemeError(f"camera fov must be in (0, 170] degrees, got {self.fov}")


#: largest frame side accepted
MAX_FRAME_SIDE = 16384


def check_size(size: tuple[int, int]) -> tuple[int, int]:
    """A frame size ``(w, h)`` as ints, each in ``[1, MAX_FRAME_SIDE]`` (raises
    :class:`TerrathemeError` otherwise)."""
    try:
        w, h = (int(s) for s in size)
    except (TypeError, ValueError):
        raise TerrathemeError(f"frame size must be (width, height), got {size!r}") from None
    if not (1 <= w <= MAX_FRAME_SIDE and 1 <= h <= MAX_FRAME_SIDE):
        raise TerrathemeError(f"frame size {w}x{h} must be within 1..{MAX_FRAME_SIDE} per side")
    return w, h


def camera_mapping(
    camera: Camera, size: tuple[int, int], texture_size: tuple[int, int] = (1, 1)
) -> PlaneMapping:
    """Eq. 1's nine coefficients for a camera and a ``size`` (w, h) frame (``texture_size``
    only places the default position). ``z`` is the ray's downward component times the
    focal length, so ``z > 0`` exactly below the horizon.
    """
    w, h = check_size(size)
    th, ps = math.radians(camera.pitch), math.radians(camera.yaw)
    ct, st, cp, sp = math.cos(th), math.sin(th), math.cos(ps), math.sin(ps)
    # focal length in pixels from the horizontal field of view
    f = (w / 2.0) / math.tan(math.radians(camera.fov) / 2.0)
    cx, cy = w / 2.0, h / 2.0
    x0 = texture_size[0] / 2.0 if camera.x is None else float(camera.x)
    y0 = texture_size[1] / 2.0 if camera.y is None else float(camera.y)
    hh = float(camera.height)
    # ray D(x, y) = f*forward + (x - cx)*right + (y - cy)*down, with
    # forward = (ct sp, -ct cp, -st), right = (cp, sp, 0), down = (-st sp, st cp, -ct);
    # the ray meets the plane at t = height / z with z = -D_z
    az, bz, cz = 0.0, ct, f * st - cy * ct
    # numerators: U = x0 + height * D_u / z, V = y0 + height * D_v / z
    au = x0 * az + hh * cp
    bu = x0 * bz - hh * st * sp
    cu = x0 * cz + hh * (f * ct * sp - cx * cp + cy * st * sp)
    av = y0 * az + hh * sp
    bv = y0 * bz + hh * st * cp
    cv = y0 * cz + hh * (-f * ct * cp - cx * sp - cy * st * cp)
    # normalise so z is about 1 at the frame centre (the mapping is homogeneous)
    s = 1.0 / f
    return PlaneMapping(au * s, bu * s, cu * s, av * s, bv * s, cv * s, az * s, bz * s, cz * s)


def view_mapping(view: Camera | PlaneMapping, size: tuple[int, int],
                 texture_size: tuple[int, int]) -> PlaneMapping:
    """Eq. 1 of ``view`` for a ``size = (w, h)`` frame: a mapping as given, a camera's
    through :func:`camera_mapping` over a ``texture_size`` texture."""
    if isinstance(view, PlaneMapping):
        return view
    if isinstance(view, Camera):
        return camera_mapping(view, size, texture_size)
    raise TerrathemeError(f"view must be a PlaneMapping or a Camera, got {type(view).__name__}")


def overview_camera(texture_size: tuple[int, int]) -> Camera:
    """A low-angle view of the whole ``texture_size`` texture, the default view.

    Looking along the longer side from a tenth of its length beyond the near edge, at a
    tenth of the distance to the far edge above the plane, aimed at the centre: a 60-degree
    view spans the texture at its far edge, the horizon near the frame's top.
    """
    w, h = (float(s) for s in texture_size)
    along = max(w, h)
    back = 1.1 * along
    height = back / 10.0
    pitch = math.degrees(math.atan2(height, back - along / 2.0))
    if h >= w:
        return Camera(height=height, pitch=pitch, yaw=0.0, fov=60.0, x=w / 2.0, y=back)
    return Camera(height=height, pitch=pitch, yaw=90.0, fov=60.0, x=w - back, y=h / 2.0)


def scaled_view(view: PlaneMapping | Camera, sx: float, sy: float) -> PlaneMapping | Camera:
    """The same view of a texture resampled by ``sx`` along U and ``sy`` along V.

    A camera keeps its angles; its height and position scale by ``sx`` (a
    camera needs ``sx == sy``, which texture reductions keep to within a texel).
    """
    if isinstance(view, PlaneMapping):
        return view.scaled(sx, sy)
    return Camera(height=view.height * sx, pitch=view.pitch, yaw=view.yaw, fov=view.fov,
                  x=None if view.x is None else view.x * sx,
                  y=None if view.y is None else view.y * sy)
