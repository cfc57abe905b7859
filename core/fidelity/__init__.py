"""How much a thematic texture looks like its photo (issue 13's measures).

Modules: ``metrics`` (``dE8`` colour layout, band-pass detail ratio,
structure similarity at 1/4 and 1/8, class IoU of the label view against
ground truth), ``cost`` (bytes per area and of the shared themes).
"""

from terratheme.core.fidelity.cost import TextureCost, texture_cost
from terratheme.core.fidelity.metrics import (
    COLOUR_SIGMA,
    DETAIL_SIGMAS,
    Fidelity,
    class_iou_scores,
    colour_error,
    detail_energy,
    detail_ratio,
    fidelity,
    majority_classes,
    structure_similarity,
)

__all__ = [
    "COLOUR_SIGMA",
    "TextureCost",
    "DETAIL_SIGMAS",
    "Fidelity",
    "colour_error",
    "detail_energy",
    "detail_ratio",
    "fidelity",
    "majority_classes",
    "class_iou_scores",
    "structure_similarity",
    "texture_cost",
]
