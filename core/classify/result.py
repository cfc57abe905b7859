"""The result of a classification: labels and a per-pixel confidence."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Classification:
    """Per-pixel classes and how sure the classifier is of them.

    ``labels`` (H, W) uint8: the masks' class values or themes 1..K, 0 only where
    transparent; ``confidence`` (H, W) float32 in [0, 1]: the winner's vote share or mixture
    posterior, 0 where transparent; ``classes``: the values the classifier can give, ascending.
    """

    labels: np.ndarray
    confidence: np.ndarray
    classes: tuple[int, ...]

    @property
    def n_classes(self) -> int:
        """Number of classes the classifier knows (not all need appear)."""
        return len(self.classes)

    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)`` of the photo."""
        return self.labels.shape  # type: ignore[return-value]
