"""The result of a classification: labels and a per-pixel confidence."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
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


def merged_class_names(classes: Iterable[int], own: Mapping[int, str] | None,
                       names: Mapping[int, str]) -> dict[int, str] | None:
    """A classifier's class names after a legend: ``names`` over ``own``, for the values in
    ``classes`` only (others skipped); None when there are none."""
    values = {int(c) for c in classes}
    given = {int(c): str(n) for c, n in names.items() if int(c) in values}
    return {**(own or {}), **given} or None
