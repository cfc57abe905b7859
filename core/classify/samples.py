"""Training samples from label masks: coarse labels, scribbles, growing them by colour.

Scribbles give only a few hundred samples on the strokes' centre lines, and strokes
lie inside class regions, so :func:`grow_labels` adds neighbours of a stroke's colour:
a one-step seeded region growing (Adams & Bischof 1994), for training samples only.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import cv2
import numpy as np
from terratheme.core.errors import TerrathemeError

#: a single mask labelling less than this share of its photo is taken for scribbles
SCRIBBLE_SHARE = 0.5
#: default colour threshold (Lab |dL| + |da| + |db|) of :func:`grow_labels` for scribbles
GROW_COLOUR = 5.0


def coarse_mask(mask: np.ndarray, scale: int, classes: Iterable[int]) -> np.ndarray:
    """Class of each coarse pixel, (ceil(H/scale), ceil(W/scale)) uint8: of ``classes``,
    the one covering most of its labelled pixels in ``mask`` (H, W) uint8 (0 unlabelled)."""
    h, w = mask.shape
    hc, wc = -(-h // scale), -(-w // scale)
    best_frac = np.zeros((hc, wc), np.float32)
    coarse = np.zeros((hc, wc), np.uint8)
    for k in classes:
        hit = (mask == k).astype(np.float32)
        if scale > 1:
            # Zero padding: padded pixels are unlabelled; INTER_AREA gives the block share.
            hit = np.pad(hit, ((0, hc * scale - h), (0, wc * scale - w)))
            hit = cv2.resize(hit, (wc, hc), interpolation=cv2.INTER_AREA)
        better = hit > best_frac
        coarse[better] = k
        best_frac[better] = hit[better]
    return coarse


def looks_like_scribbles(pairs: Sequence[tuple[np.ndarray, np.ndarray]],
                         ignore_classes: Sequence[int] = ()) -> bool:
    """True for one ``(photo, mask)`` pair with under ``SCRIBBLE_SHARE`` of the mask
    labelled (non-zero, not in ``ignore_classes``)."""
    if len(pairs) != 1:
        return False
    mask = np.asarray(pairs[0][1])
    labelled = (mask > 0) & ~np.isin(mask, tuple(ignore_classes))
    return bool(labelled.mean() < SCRIBBLE_SHARE)


def grow_labels(coarse: np.ndarray, lab: np.ndarray, threshold: float) -> np.ndarray:
    """``coarse`` (h, w) uint8 classes (0 unlabelled) plus each unlabelled 4-neighbour of a
    labelled pixel whose coarse Lab ``lab`` (h, w, 3) differs from it by under
    ``threshold`` (|dL| + |da| + |db|); a pixel that would take two classes stays 0."""
    h, w = coarse.shape
    taken = np.zeros((h, w), np.uint8)
    conflict = np.zeros((h, w), bool)
    # Each of the four neighbours in turn: (rows, cols) of the pixel and of its neighbour.
    for dst, src in (((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
                     ((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
                     ((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                     ((slice(None), slice(None, -1)), (slice(None), slice(1, None)))):
        near = coarse[src]
        close = np.abs(lab[dst] - lab[src]).sum(axis=2) < threshold
        hit = (coarse[dst] == 0) & (near > 0) & close
        t = taken[dst]
        conflict[dst] |= hit & (t > 0) & (t != near)
        t[hit] = near[hit]
    taken[conflict] = 0
    return np.where(coarse > 0, coarse, taken).astype(np.uint8)


def check_class_image(
    image: object, what: str, shape: tuple[int, int] | None = None
) -> np.ndarray:
    """A label mask, scribble mask or label image as (H, W) uint8 class values 0..255.

    ``image`` is (H, W) or (H, W, 1) integers or bools of the photo's ``shape`` when given;
    ``what`` names it in errors ("label mask 2"). A view when it is uint8 already.
    """
    arr = np.asarray(image)
    # A one-channel third axis (a grey image read as (H, W, 1)) is dropped.
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim != 2:
        raise TerrathemeError(f"{what}: shape {arr.shape} is not single-channel (H, W)")
    if shape is not None and arr.shape != tuple(shape):
        raise TerrathemeError(
            f"{what} is {arr.shape[1]} x {arr.shape[0]} pixels but its photo is "
            f"{shape[1]} x {shape[0]}: a mask must have the photo's size"
        )
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise TerrathemeError(f"{what} has no pixels (shape {arr.shape})")
    if arr.dtype.kind not in "iub":
        raise TerrathemeError(f"{what}: values must be integers, not {arr.dtype}")
    if arr.dtype.itemsize > 1 or arr.dtype.kind == "i":
        # Only wider or signed integers can leave 0..255 (no pass over uint8 or bool pixels).
        lo, hi = int(arr.min()), int(arr.max())
        if lo < 0 or hi > 255:
            raise TerrathemeError(f"{what}: class values must be 0..255, got {lo}..{hi}")
    return arr.astype(np.uint8, copy=False)
