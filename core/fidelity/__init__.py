"""How much a thematic texture looks like its photo (issue 13's measures).

Modules: ``metrics`` (``dE8`` colour layout, band-pass detail ratio,
structure IoU of the label view against ground truth).
"""

from core.fidelity.metrics import (
    COLOUR_SIGMA,
    DETAIL_SIGMAS,
    colour_error,
    detail_energy,
    detail_ratio,
    majority_classes,
    structure_scores,
)

__all__ = [
    "COLOUR_SIGMA",
    "DETAIL_SIGMAS",
    "colour_error",
    "detail_energy",
    "detail_ratio",
    "majority_classes",
    "structure_scores",
]
