"""The colour map: a low-resolution colour gain laid over a thematic texture.

A class alone carries one texture and one colour; the photo's slow colour
changes inside a class (wet and dry sand, sunlit and shaded grass) are lost
(issue 13). Terrain engines keep such changes in a *macro variation* or
*colour* map: a coarse RGB image multiplied over the tiled detail textures.
terratheme's colour map is that image:

* ``pixels`` ``(mh, mw, 3) uint8``: a per-channel gain, ``value / 128``
  (:data:`NEUTRAL` = no change, 255 = x1.99);
* ``scale``: texels per map pixel along both axes; map pixel ``(i, j)``
  covers texels ``[i*scale, (i+1)*scale) x [j*scale, (j+1)*scale)`` of the
  full texture and sits at its centre, so the map of a ``W x H`` texture is
  ``ceil(H/scale) x ceil(W/scale)``;
* at texel ``X`` the gain is the bilinear interpolation of the map at
  ``(X + 0.5) / scale - 0.5`` (clamped at the edges), in exact integer
  arithmetic (:mod:`core.render.colour_map`), so every renderer and every
  region agrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.errors import TerrathemeError
from core.io.codec import decode_image

#: the stored value that leaves a texel unchanged
NEUTRAL = 128
#: largest texels per map pixel
MAX_SCALE = 4096


@dataclass(frozen=True, eq=False)
class ColourMap:
    """A per-channel colour gain over the texture (see the module docstring).

    Attributes
    ----------
    pixels : (mh, mw, 3) uint8 ndarray
        Gain times 128 (read-only copy).
    scale : int
        Texels per map pixel, 1..4096.
    codec, data : str and bytes, or None
        The map as it ships (:mod:`core.io.codec`): ``pixels`` are these bytes
        decoded (:meth:`from_bytes`), so every copy renders alike.
    """

    pixels: np.ndarray
    scale: int
    codec: str | None = None
    data: bytes | None = None

    def __post_init__(self) -> None:
        arr = np.asarray(self.pixels)
        if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
            raise TerrathemeError(f"colour map must be (h, w, 3), got shape {arr.shape}")
        if arr.dtype != np.uint8:
            raise TerrathemeError(f"colour map must be uint8, got {arr.dtype}")
        if isinstance(self.scale, bool) or not isinstance(self.scale, int | np.integer) or not (
                1 <= int(self.scale) <= MAX_SCALE):
            raise TerrathemeError(f"colour map scale must be an integer 1..{MAX_SCALE}, "
                                  f"got {self.scale!r}")
        frozen = np.array(arr, dtype=np.uint8, order="C")
        frozen.setflags(write=False)
        object.__setattr__(self, "pixels", frozen)
        object.__setattr__(self, "scale", int(self.scale))

    @classmethod
    def from_bytes(cls, data: bytes, codec: str, scale: int,
                   shape: tuple[int, int] | None = None) -> ColourMap:
        """The map shipped as ``data`` in ``codec`` (``shape`` = expected ``(mh, mw)``)."""
        pixels = decode_image(data, codec=codec, shape=shape)
        if pixels.shape[2] < 3:
            raise TerrathemeError(f"colour map must be RGB, the {codec} image has "
                                  f"{pixels.shape[2]} channel(s)")
        return cls(pixels[:, :, :3], scale, codec, bytes(data))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ColourMap):
            return NotImplemented
        return self.scale == other.scale and np.array_equal(self.pixels, other.pixels)

    @staticmethod
    def shape_for(texture_size: tuple[int, int], scale: int) -> tuple[int, int]:
        """``(mh, mw)`` of the map covering a ``(W, H)`` texture at ``scale``."""
        w, h = texture_size
        return -(-h // scale), -(-w // scale)

    def check_covers(self, texture_size: tuple[int, int]) -> None:
        """Raise unless the map has exactly the shape for a ``(W, H)`` texture."""
        want = self.shape_for(texture_size, self.scale)
        if self.pixels.shape[:2] != want:
            raise TerrathemeError(
                f"colour map is {self.pixels.shape[1]} x {self.pixels.shape[0]} at scale "
                f"{self.scale}, but a {texture_size[0]} x {texture_size[1]} texture needs "
                f"{want[1]} x {want[0]}"
            )

    @property
    def nbytes(self) -> int:
        """Bytes as shipped (``data``), else of the raw pixels."""
        return len(self.data) if self.data is not None else int(self.pixels.nbytes)
