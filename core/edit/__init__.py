"""Editing a thematic texture by hand: the document model behind the editor (no Qt).

:class:`EditDocument` holds everything the editor edits (grid, themes, scribbles,
photo, confidence, kept prior), with one undo history and plain-Python change events;
tools are pure functions returning vertex selections.
"""

from terratheme.core.edit.atoms import Atom, EditAtom, MultiAtom, merge_atoms, replace_atoms
from terratheme.core.edit.changes import Change
from terratheme.core.edit.classification import (
    ClassificationUpdate,
    ClassifyMode,
    classification_changes,
    run_classification,
)
from terratheme.core.edit.document import EditDocument
from terratheme.core.edit.events import (
    ColourMapChange,
    ConfidenceChange,
    DocumentEvents,
    Emitter,
    GridChange,
    HistoryChange,
    PriorChange,
    ScribbleChange,
    ThemeChange,
)
from terratheme.core.edit.fidelity import fidelity_map, heat_colours
from terratheme.core.edit.history import History, Step
from terratheme.core.edit.layers import (
    Layer,
    photo_extent,
    validate_confidence,
)
from terratheme.core.edit.preview import RenderPreview, dirty_cells, dirty_region
from terratheme.core.edit.tools import (
    VertexSelection,
    capsule_footprint,
    eyedropper,
    flood_footprint,
    rect_footprint,
)
from terratheme.core.edit.uncertainty import (
    UNCERTAIN_SHARE,
    KeptPrior,
    next_kept_prior,
    scribble_classes,
    uncertain_mask,
    uncertainty_rgba,
)

__all__ = [
    "UNCERTAIN_SHARE",
    "Atom",
    "Change",
    "ClassificationUpdate",
    "ClassifyMode",
    "ConfidenceChange",
    "DocumentEvents",
    "EditAtom",
    "EditDocument",
    "Emitter",
    "ColourMapChange",
    "GridChange",
    "History",
    "HistoryChange",
    "KeptPrior",
    "Layer",
    "MultiAtom",
    "PriorChange",
    "RenderPreview",
    "ScribbleChange",
    "Step",
    "ThemeChange",
    "VertexSelection",
    "capsule_footprint",
    "classification_changes",
    "run_classification",
    "dirty_cells",
    "dirty_region",
    "eyedropper",
    "fidelity_map",
    "flood_footprint",
    "heat_colours",
    "merge_atoms",
    "next_kept_prior",
    "photo_extent",
    "rect_footprint",
    "replace_atoms",
    "scribble_classes",
    "uncertain_mask",
    "uncertainty_rgba",
    "validate_confidence",
]
