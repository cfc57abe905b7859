"""The peers of bench_fidelity: the photo as JPEG, WebP or AVIF at a byte budget.

A thematic texture costs ``area_bytes`` per area (grid + colour map,
:func:`core.fidelity.texture_cost`); its peer is the photo itself coded in
that many bytes. Each codec keeps one fixed, reasonable quality
(:data:`CODECS`); the photo is downscaled (``cv2.INTER_AREA``) to the
largest width whose encoding fits the budget (widths doubled from
:data:`MIN_WIDTH`, then bisected; aspect kept), decoded and upscaled back
(``cv2.INTER_CUBIC``) to the photo's size, then scored with the same measures as the texture
(:func:`core.fidelity.colour_error`, :func:`core.fidelity.detail_ratio`).
Encoders are imagecodecs' (libjpeg-turbo with optimised Huffman tables,
libwebp method 6, libavif speed 6): benchmark-only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import imagecodecs
import numpy as np
from terratheme.core.fidelity import colour_error, detail_ratio

#: the narrowest photo a peer may be downscaled to, pixels
MIN_WIDTH = 8


@dataclass(frozen=True)
class Codec:
    """One peer codec at its fixed quality."""

    name: str
    quality: int
    encode: Callable[[np.ndarray], bytes]
    decode: Callable[[bytes], np.ndarray]


CODECS = (
    Codec("jpeg", 75, lambda a: imagecodecs.jpeg8_encode(a, level=75, optimize=True),
          imagecodecs.jpeg8_decode),
    Codec("webp", 75, lambda a: imagecodecs.webp_encode(a, level=75, lossless=False, method=6),
          imagecodecs.webp_decode),
    Codec("avif", 60, lambda a: imagecodecs.avif_encode(a, level=60, speed=6),
          imagecodecs.avif_decode),
)


def _downscaled(photo: np.ndarray, width: int) -> np.ndarray:
    h, w = photo.shape[:2]
    height = max(1, round(h * width / w))
    return cv2.resize(photo, (width, height), interpolation=cv2.INTER_AREA)


def fit_budget(photo: np.ndarray, codec: Codec, budget: int) -> tuple[np.ndarray, int, int] | None:
    """The photo through ``codec`` in at most ``budget`` bytes, back at full size.

    Parameters
    ----------
    photo : (H, W, 3) uint8 ndarray
    codec : Codec
    budget : int
        Bytes the encoding may take.

    Returns
    -------
    (decoded, width, nbytes) or None
        ``decoded``: (H, W, 3) uint8, upscaled back; ``width``: the coded width;
        None when not even :data:`MIN_WIDTH` pixels wide fits (JPEG's headers
        alone take about 600 bytes).
    """
    h, w = photo.shape[:2]
    best: tuple[int, bytes] | None = None
    # Double the width from the narrowest until the encoding no longer fits ...
    lo, hi = MIN_WIDTH, MIN_WIDTH
    while True:
        data = codec.encode(_downscaled(photo, hi))
        if len(data) > budget:
            break
        best, lo = (hi, data), hi + 1
        if hi == w:
            break
        hi = min(w, 2 * hi)
    hi -= 1
    # ... then bisect between the last width that fits and the first that does not.
    while best is not None and lo <= hi:
        mid = (lo + hi) // 2
        data = codec.encode(_downscaled(photo, mid))
        if len(data) <= budget:
            best, lo = (mid, data), mid + 1
        else:
            hi = mid - 1
    if best is None:
        return None
    width, data = best
    small = np.asarray(codec.decode(data))[:, :, :3]
    back = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    return back, width, len(data)


def score_peers(photo: np.ndarray, budget: int) -> dict[str, dict | None]:
    """Every codec of :data:`CODECS` at ``budget`` bytes, scored like the texture.

    Returns
    -------
    {codec name: {"bytes", "width", "dE8", "detail"} or None}
    """
    out: dict[str, dict | None] = {}
    for codec in CODECS:
        fitted = fit_budget(photo, codec, budget)
        if fitted is None:
            out[codec.name] = None
            continue
        decoded, width, nbytes = fitted
        out[codec.name] = {"bytes": nbytes, "width": width,
                           "dE8": round(colour_error(decoded, photo), 3),
                           "detail": round(detail_ratio(decoded, photo), 3)}
    return out
