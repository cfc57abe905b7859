"""Bring a user's photo to the form the classifier works on.

The classifier works on 8-bit RGB plus a mask of the pixels with data (alpha 0 is no
data: never sampled nor classified). A 2nd or 4th channel here *is* alpha; whether a
file's extra band is alpha is the file's say (an RGB + near-infrared TIFF), so read
photos with ``read_image(path, bands=Bands.PHOTO)``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from terratheme.core.errors import TerrathemeError


class PreparedPhoto(NamedTuple):
    """A photo as :func:`prepare_photo` leaves it: ``rgb`` (H, W, 3) uint8, C-contiguous,
    and ``valid`` (H, W) bool or None (every pixel has data)."""

    rgb: np.ndarray
    valid: np.ndarray | None


def prepare_photo(photo: np.ndarray | PreparedPhoto) -> PreparedPhoto:
    """Check a photo and convert it to 8-bit RGB plus a validity mask.

    ``photo`` is (H, W[, 1|2|3|4]) uint8, uint16 or float in [0, 1], or a
    :class:`PreparedPhoto`, returned as it is (a conversion prepares once and passes it
    on). Transparent pixels get the nearest opaque colour; ``valid`` is False where
    alpha is 0.
    """
    if isinstance(photo, PreparedPhoto):
        return photo
    arr = np.asarray(photo)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 2, 3, 4):
        raise TerrathemeError(
            f"photo has shape {arr.shape}; expected (H, W, 3) RGB or (H, W, 4) RGBA"
        )
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise TerrathemeError(f"photo has no pixels (shape {arr.shape})")
    # Scale the pixel type to 8 bits (16-bit: divide by 257, so 65535 -> 255).
    if arr.dtype == np.uint8:
        img8 = arr
    elif arr.dtype == np.uint16:
        img8 = ((arr.astype(np.uint32) + 128) // 257).astype(np.uint8)
    elif np.issubdtype(arr.dtype, np.floating):
        unit = np.clip(np.nan_to_num(arr, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
        img8 = (unit * 255.0 + 0.5).astype(np.uint8)
    else:
        raise TerrathemeError(f"photo pixel type {arr.dtype} is not supported (uint8, uint16)")
    # Split off alpha (grey + alpha has 2 channels, RGB + alpha 4).
    channels = img8.shape[2]
    valid = None
    if channels in (2, 4):
        valid = img8[:, :, -1] > 0
        img8 = img8[:, :, :-1]
        if not valid.any():
            raise TerrathemeError("photo is fully transparent: no pixel to classify")
        if valid.all():
            valid = None
        else:
            # Give transparent pixels the colour of the nearest opaque pixel, so their
            # (meaningless) colour does not bleed into neighbours' smoothed features.
            from scipy.ndimage import distance_transform_edt

            _, (iy, ix) = distance_transform_edt(~valid, return_indices=True)
            img8 = img8[iy, ix]
    if img8.shape[2] == 1:
        img8 = np.repeat(img8, 3, axis=2)
    return PreparedPhoto(np.ascontiguousarray(img8), valid)
