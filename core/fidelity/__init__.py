"""How much a thematic texture looks like its photo: ``metrics`` (dE8, detail ratio,
structure similarity) and ``cost`` (bytes per area and of the themes)."""

from terratheme.core.fidelity.cost import TextureCost, texture_cost
from terratheme.core.fidelity.metrics import (
    COLOUR_SIGMA,
    DETAIL_SIGMAS,
    Fidelity,
    Reference,
    colour_error,
    detail_energy,
    detail_placement,
    detail_ratio,
    fidelity,
    reference,
    structure_similarity,
)

__all__ = [
    "COLOUR_SIGMA",
    "TextureCost",
    "DETAIL_SIGMAS",
    "Fidelity",
    "colour_error",
    "detail_energy",
    "detail_placement",
    "detail_ratio",
    "fidelity",
    "Reference",
    "reference",
    "structure_similarity",
    "texture_cost",
]
