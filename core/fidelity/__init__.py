"""How much a thematic texture looks like its photo (issue 13's measures).

Modules: ``metrics`` (``dE8`` colour layout, band-pass detail ratio,
structure IoU of the label view against ground truth), ``cost`` (bytes per
area and of the shared themes).
"""

from terratheme.core.fidelity.cost import TextureCost, texture_cost
from terratheme.core.fidelity.metrics import (
    COLOUR_SIGMA,
    DETAIL_SIGMAS,
    Fidelity,
    colour_error,
    detail_energy,
    detail_ratio,
    fidelity,
    majority_classes,
    structure_scores,
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
    "structure_scores",
    "structure_similarity",
    "texture_cost",
]
