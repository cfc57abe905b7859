"""Training samples from label masks: coarse labels, scribbles, growing them by colour.

:func:`coarse_mask` gives each coarse pixel the class covering most of its
labelled photo pixels.

A user's strokes are short and thin: at the default 8x8 coarse pixels a
30-pixel stroke touches about four coarse pixels, so a photo's scribbles give
the forest only a few hundred samples, all on the strokes' centre lines.
Strokes are painted inside class regions, so the coarse pixels right next to
a stroke whose colour matches the stroke's are very likely of the stroke's
class too: :func:`grow_labels` adds them as samples (one ring of 4-neighbours,
colour difference under ``threshold``; a pixel next to strokes of two classes
is left out). It is a cautious, one-step form of seeded region growing
(Adams & Bischof 1994), used for the training samples only.

:func:`check_class_image` is the one check of a class-value image (label
mask, scribble mask, label image) that training, conversion and the grid vote
share.
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
    """Class of each coarse pixel: the class covering most of its labelled pixels.

    Parameters
    ----------
    mask : (H, W) uint8 ndarray
        0 = unlabelled.
    scale : int
    classes : iterable of int
        Classes to keep (others count as unlabelled).

    Returns
    -------
    coarse : (ceil(H/scale), ceil(W/scale)) uint8 ndarray, 0 = no label
    """
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

    Parameters
    ----------
    image : (H, W) or (H, W, 1) integer or bool array-like
    what : str
        What it is, for the errors ("label mask 2", "label image", ...).
    shape : (H, W), optional
        The photo's size, which the image must have.

    Returns
    -------
    (H, W) uint8 ndarray
        A view of ``image`` when it is uint8 already.
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
    lo, hi = int(arr.min()), int(arr.max())
    if lo < 0 or hi > 255:
        raise TerrathemeError(f"{what}: class values must be 0..255, got {lo}..{hi}")
    return arr.astype(np.uint8, copy=False)
