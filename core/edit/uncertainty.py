"""Where the classifier is unsure, and the class prior kept between scribble rounds.

The editor's "Show uncertainty" view (``app/editor/window.py``,
the Qt side) tints the photo pixels whose confidence
(``core.classify.Classification.confidence``: the winning class's vote share)
is among the lowest ``UNCERTAIN_SHARE`` of the photo, after a ``FILTER_SIZE`` x
``FILTER_SIZE`` majority filter so they read as regions a user can correct
with a second round of strokes.

The *kept prior*: a scribble classification estimates class-prior weights
from the blind first strokes (:mod:`core.classify.prior`). Correction strokes
are painted where the result is wrong, so re-estimating from them hurts
(benchmarks/classify_corrections.py: mean mIoU 0.557 re-estimated vs 0.598
kept); the weights of the first run are reused as long as the set of
scribbled class values is the same (:class:`KeptPrior`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import cv2
import numpy as np

#: share of the photo, by lowest confidence, shown as uncertain
UNCERTAIN_SHARE = 0.10
#: side of the majority (binary median) filter, photo pixels
FILTER_SIZE = 9
#: RGBA tint of uncertain pixels (magenta, translucent)
TINT = (255, 0, 200, 130)


def uncertain_mask(confidence: np.ndarray, share: float = UNCERTAIN_SHARE,
                   size: int = FILTER_SIZE) -> np.ndarray:
    """Pixels whose confidence is in the lowest ``share`` of the photo, as regions.

    The threshold is the ``share`` quantile of the confidence; pixels at it
    count as uncertain unless it is the top confidence (a photo the
    classifier is equally sure of everywhere has no uncertain pixel). Then a
    ``size`` x ``size`` majority filter (median of the binary mask) removes
    specks and fills pinholes.

    Parameters
    ----------
    confidence : (H, W) float ndarray in [0, 1]
    share : float in (0, 1)
    size : odd int >= 1

    Returns
    -------
    mask : (H, W) bool ndarray
    """
    conf = np.asarray(confidence, np.float32)
    if conf.size == 0:
        return np.zeros(conf.shape, bool)
    # Threshold at the share-quantile; ties count unless they are the top value.
    q = np.quantile(conf, share)
    low = conf <= q if q < conf.max() else conf < q
    if size <= 1:
        return low
    # Majority vote over size x size neighbourhoods (binary median, edges replicated).
    return cv2.medianBlur(low.astype(np.uint8) * 255, size) > 127


def uncertainty_rgba(mask: np.ndarray, tint: tuple[int, int, int, int] = TINT) -> np.ndarray:
    """The overlay image: ``tint`` on uncertain pixels, transparent elsewhere.

    Parameters
    ----------
    mask : (H, W) bool ndarray

    Returns
    -------
    rgba : (H, W, 4) uint8 ndarray
    """
    out = np.zeros(mask.shape + (4,), np.uint8)
    out[mask] = tint
    return out


def scribble_classes(scribbles: np.ndarray | None) -> frozenset[int]:
    """Class values painted in a scribble layer (0 = unlabelled is not a class)."""
    if scribbles is None:
        return frozenset()
    return frozenset(int(v) for v in np.unique(scribbles)) - {0}


@dataclass(frozen=True)
class KeptPrior:
    """Class weights of the first scribble classification of a set of class values.

    Attributes
    ----------
    weights : mapping of class value -> weight
    classes : frozenset of int
        The scribbled class values of that classification.
    """

    weights: Mapping[int, float]
    classes: frozenset[int]

    def applies_to(self, classes: frozenset[int]) -> bool:
        """Whether a classification of these scribbled classes reuses the weights."""
        return bool(classes) and classes == self.classes


def next_kept_prior(kept: KeptPrior | None, classes: frozenset[int],
                    weights: Mapping[int, float] | None) -> KeptPrior | None:
    """The kept prior after a scribble classification of ``classes`` gave ``weights``.

    A kept prior that still applies stays; otherwise the run's weights (an
    estimate afresh) become the kept prior, or nothing when it had none
    (one class, or no correction).
    """
    if kept is not None and kept.applies_to(classes):
        return kept
    if weights is None or not classes:
        return None
    return KeptPrior(dict(weights), frozenset(classes))
