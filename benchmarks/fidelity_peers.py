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

Issue 34 (:func:`best_peers`): JPEG and AVIF each at their best operating
point for the budget, a scale x quality search: for every quality of
:data:`QUALITY_LADDER` the largest width that fits, scored with the two
structure scores too (:func:`core.fidelity.structure_similarity` at 1/4 and
1/8); the peer's figure on each axis is its best over the qualities (lowest
dE8, highest structure; detail and placement at the point of highest structure 1/4), so the
texture is held to the strictest codec.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import imagecodecs
import numpy as np
from terratheme.core.fidelity import (
    colour_error,
    detail_placement,
    detail_ratio,
    structure_similarity,
)
from terratheme.core.io.codec import decode_image, encode_image

#: the narrowest photo a peer may be downscaled to, pixels
MIN_WIDTH = 8


@dataclass(frozen=True)
class Codec:
    """One peer codec at its fixed quality."""

    name: str
    quality: int
    encode: Callable[[np.ndarray], bytes]
    decode: Callable[[bytes], np.ndarray]


def _avif_decode(data: bytes):
    """AVIF as the colour map codes it (4:4:4, BT.709: imagecodecs' default matrix
    shifts colours by about 1 dE, which would handicap the peer)."""
    return decode_image(data, codec="avif")


CODECS = (
    Codec("jpeg", 75, lambda a: imagecodecs.jpeg8_encode(a, level=75, optimize=True),
          imagecodecs.jpeg8_decode),
    Codec("webp", 75, lambda a: imagecodecs.webp_encode(a, level=75, lossless=False, method=6),
          imagecodecs.webp_decode),
    Codec("avif", 60, lambda a: encode_image(a, codec="avif", quality=60), _avif_decode),
)

#: codec name -> (encoder at a quality, decoder): the peers of issue 34
PEER_MAKERS = {
    "jpeg": (lambda q: lambda a: imagecodecs.jpeg8_encode(a, level=q, optimize=True),
             imagecodecs.jpeg8_decode),
    "avif": (lambda q: lambda a: encode_image(a, codec="avif", quality=q), _avif_decode),
}
#: qualities of the scale x quality search
QUALITY_LADDER = {"jpeg": (20, 40, 60, 80, 92), "avif": (20, 35, 50, 65, 80)}


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


def placement_score(decoded: np.ndarray, photo: np.ndarray) -> float:
    """The RMS over blocks of :func:`core.fidelity.detail_placement` (0: the photo's fine
    texture in every block, at its strength), rounded as the benchmarks report it."""
    return round(float(np.sqrt(np.mean(detail_placement(decoded, photo) ** 2))), 3)


def score_image(decoded: np.ndarray, photo: np.ndarray) -> dict[str, float]:
    """dE8, detail, placement (:func:`placement_score`) and structure at 1/4 and 1/8 of a
    decoded image against its photo."""
    return {"dE8": round(colour_error(decoded, photo), 3),
            "detail": round(detail_ratio(decoded, photo), 3),
            "placement": placement_score(decoded, photo),
            "s4": round(structure_similarity(decoded, photo, 4), 4),
            "s8": round(structure_similarity(decoded, photo, 8), 4)}


def best_peers(photo: np.ndarray, budget: int) -> dict[str, dict | None]:
    """JPEG and AVIF at their best operating point for ``budget`` bytes (module docstring).

    Returns
    -------
    {codec: {"dE8", "s4", "s8", "detail", "points": [{"quality", "width", "bytes", ...}]}
    or None when no quality fits}
    """
    out: dict[str, dict | None] = {}
    for name, (make, decode) in PEER_MAKERS.items():
        points = []
        for q in QUALITY_LADDER[name]:
            fitted = fit_budget(photo, Codec(name, q, make(q), decode), budget)
            if fitted is not None:
                decoded, width, nbytes = fitted
                points.append({"quality": q, "width": width, "bytes": nbytes,
                               **score_image(decoded, photo)})
        if not points:
            out[name] = None
            continue
        top = max(points, key=lambda p: p["s4"])
        out[name] = {"dE8": min(p["dE8"] for p in points), "s4": top["s4"],
                     "s8": max(p["s8"] for p in points), "detail": top["detail"],
                     "placement": top["placement"],
                     "points": points}
    return out
