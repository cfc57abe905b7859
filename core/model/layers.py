"""The optional per-pixel layers of a project (photo, scribbles, ...), as one table.

The project's constructor, saver and loader loop over :data:`LAYERS`; adding a layer
is one :class:`LayerSpec` here plus a field of that name (default None) on
:class:`core.model.project.ThematicTexture`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from terratheme.core.errors import TerrathemeError

#: most pixels of one layer (``convert`` stores photos up to 40 Mpx)
MAX_LAYER_PIXELS = 1 << 27


@dataclass(frozen=True)
class LayerSpec:
    """An optional per-pixel layer of a project: its attribute, member and checks.

    ``name`` is the :class:`ThematicTexture` attribute, manifest ``"layers"`` entry
    and ``<name>.npy`` member; ``channels`` None means ``(H, W)``, k ``(H, W, k)``.
    ``same_size_as``: ``"grid"`` (the grid's vertex shape), another layer's name
    (its ``(H, W)`` when both are present), or None (up to :data:`MAX_LAYER_PIXELS`).
    """

    name: str
    channels: int | None
    dtype: np.dtype
    same_size_as: str | None = None

    @property
    def member(self) -> str:
        return f"{self.name}.npy"

    @property
    def shape_text(self) -> str:
        return "(H, W)" if self.channels is None else f"(H, W, {self.channels})"


#: The optional layers, in file order (saving, loading, equality and the checks follow).
LAYERS = (
    LayerSpec("photo", 3, np.dtype(np.uint8)),
    LayerSpec("scribbles", None, np.dtype(np.uint8), same_size_as="photo"),
)
LAYER_BY_NAME = {spec.name: spec for spec in LAYERS}


def check_layer(spec: LayerSpec, array: object, sizes: dict[str, tuple[int, int]]) -> np.ndarray:
    """``array`` checked against ``spec`` (dimensions, channels, dtype, size), C-contiguous.

    ``sizes`` holds the ``(H, W)`` of the grid (``"grid"``) and of the layers checked so
    far; raises TerrathemeError.
    """
    if not isinstance(array, np.ndarray):
        raise TerrathemeError(f"{spec.name} layer must be a numpy array, "
                              f"not {type(array).__name__}")
    ndim = 2 if spec.channels is None else 3
    if array.ndim != ndim or (spec.channels is not None and array.shape[2] != spec.channels):
        raise TerrathemeError(f"{spec.name} layer must be {spec.shape_text}, "
                              f"got shape {array.shape}")
    if array.dtype != spec.dtype:
        raise TerrathemeError(f"{spec.name} layer must be {spec.dtype}, got {array.dtype}")
    h, w = array.shape[:2]
    if h < 1 or w < 1:
        raise TerrathemeError(f"{spec.name} layer has no pixels (shape {array.shape})")
    if h * w > MAX_LAYER_PIXELS:
        raise TerrathemeError(f"{spec.name} layer of {w} x {h} pixels is over the limit of "
                              f"{MAX_LAYER_PIXELS:,} pixels")
    want = sizes.get(spec.same_size_as) if spec.same_size_as else None
    if want is not None and (h, w) != want:
        raise TerrathemeError(f"{spec.name} layer is {w} x {h} but the {spec.same_size_as} "
                              f"is {want[1]} x {want[0]}")
    return np.ascontiguousarray(array)
