"""Where the classifier is unsure, and the class prior kept between scribble rounds.

The uncertainty view tints the photo pixels whose confidence is among the lowest
``UNCERTAIN_SHARE``, majority-filtered into regions a user can correct. The kept prior:
correction strokes are painted where the result is wrong, so the first run's class
weights are reused while the scribbled classes stay the same (docs/decisions.md,
``kept_weights``).
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
    """(H, W) bool: pixels whose confidence is in the lowest ``share`` (the quantile, ties
    included unless it is the top confidence), then a ``size`` x ``size`` majority filter.
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
    """The (H, W, 4) uint8 overlay: ``tint`` on ``mask`` pixels, transparent elsewhere."""
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
    """Class weights (class value -> weight) of the first scribble classification of the
    scribbled class values ``classes``."""

    weights: Mapping[int, float]
    classes: frozenset[int]

    def applies_to(self, classes: frozenset[int]) -> bool:
        """Whether a classification of these scribbled classes reuses the weights."""
        return bool(classes) and classes == self.classes


def next_kept_prior(kept: KeptPrior | None, classes: frozenset[int],
                    weights: Mapping[int, float] | None) -> KeptPrior | None:
    """The kept prior after a scribble run of ``classes`` gave ``weights``: the old one while it
    applies, else the run's weights (or None).
    """
    if kept is not None and kept.applies_to(classes):
        return kept
    if weights is None or not classes:
        return None
    return KeptPrior(dict(weights), frozenset(classes))
