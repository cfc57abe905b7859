"""What a thematic texture costs in bytes: per area (grid + colour map) and shared (themes).

The themes are a library shared by every area of a terrain, so a texture's own
cost is ``area_bytes``: its index grid packed along a space-filling curve
(:func:`core.packing.pack`, compact layout) plus its colour map as it ships.
``theme_bytes`` is the library's, every theme as lossless PNG.
"""

from __future__ import annotations

from dataclasses import dataclass

from terratheme.core.io.codec import encode_image
from terratheme.core.model.project import ThematicTexture
from terratheme.core.packing import pack


@dataclass(frozen=True)
class TextureCost:
    """Bytes of a thematic texture: ``grid_bytes`` (compact packed layer),
    ``colour_map_bytes`` (as it ships: its codec's bytes, a raw map's pixels; 0 without
    one) and
    ``theme_bytes`` (the library as PNG files)."""

    grid_bytes: int
    colour_map_bytes: int
    theme_bytes: int

    @property
    def area_bytes(self) -> int:
        """What the area itself costs: grid + colour map."""
        return self.grid_bytes + self.colour_map_bytes

    def as_dict(self) -> dict:
        """JSON-ready (``terratheme info PROJECT --json``)."""
        return {"area_bytes": self.area_bytes, "grid_bytes": self.grid_bytes,
                "colour_map_bytes": self.colour_map_bytes, "theme_bytes": self.theme_bytes}


def texture_cost(project: ThematicTexture) -> TextureCost:
    """The bytes of a project's texture (see the module docstring)."""
    grid = len(pack(project.grid.indices, curve="auto").to_bytes())
    cmap = 0 if project.colour_map is None else project.colour_map.nbytes
    themes = sum(len(encode_image(t.texture, codec="png")) for t in project.library)
    return TextureCost(grid, cmap, themes)
