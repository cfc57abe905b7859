"""Unity terrain: RGBA8 splatmaps, theme textures, a terrain-layer description and an editor script.

Splatmap ``s`` holds themes ``4s..4s+3`` in RGBA, square, a power of two 16..4096
(``TerrainData.alphamapResolution``), row 0 the north edge, tiles sharing border texels.
The colour map ships as ``colour_map.png`` with each tile's ``colour_map_st``; the editor
script and shaders of :data:`UNITY_SCRIPTS` build the terrain in Unity (docs/engines.md).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from terratheme.core.errors import OptionError
from terratheme.core.exchange.colour import COLOUR_MAP, unity_colour_st
from terratheme.core.exchange.layout import ExportLayout, tiled_layout
from terratheme.core.exchange.options import ExportOptions
from terratheme.core.exchange.plan import (
    STORED_ALPHA,
    ExportPlan,
    common_manifest,
    layer_names,
    map_plan,
    piece_weights,
    pixel_spacing,
    theme_files,
    write_manifest,
    write_shared_files,
)
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.io.images import write_image
from terratheme.core.model.project import ThematicTexture

#: alphamap (control texture) resolutions Unity's terrain accepts
UNITY_RESOLUTIONS = tuple(1 << k for k in range(4, 13))
MANIFEST = "terratheme_unity.json"
SCRIPT = "Editor/TerrathemeImporter.cs"
#: the export's editor script and terrain shaders: name in the export, file in ``scripts``
UNITY_SCRIPTS = {
    SCRIPT: "TerrathemeImporter.cs",
    "Shaders/TerrathemeTerrain.shader": "TerrathemeTerrain.shader",
    "Shaders/TerrathemeTerrainAddPass.shader": "TerrathemeTerrainAddPass.shader",
    "Shaders/TerrathemeColourMap.cginc": "TerrathemeColourMap.cginc",
}
_SCRIPTS = Path(__file__).resolve().parent / "scripts"
Progress = Callable[[int, int], None]


def _check_resolution(r: int, what: str) -> None:
    """``what``: the option, as an :class:`OptionError` template (``{tile}``)."""
    if r not in UNITY_RESOLUTIONS:
        raise OptionError(
            f"{what} {r} is not a Unity alphamap resolution (a power of two from 16 to 4096: "
            f"{', '.join(map(str, UNITY_RESOLUTIONS))})"
        )


def unity_layout(texture_size: tuple[int, int], options: ExportOptions
                 ) -> tuple[ExportLayout, list[str]]:
    """The splatmap layout of an export, and notes for the user.

    Untiled: one square ``R x R`` alphamap (default the power of two nearest
    above the texture's longer side, at most 4096). Tiled: ``T x T`` tiles
    (``T`` an accepted resolution), the whole map ``k * (T - 1) + 1`` pixels
    each way (default: at least one pixel per texel).
    """
    wtex, htex = texture_size
    notes = []
    if options.tile is None:
        if options.size is not None:
            w, h = options.size
            if w != h:
                raise OptionError(f"Unity's alphamap is square: {{size}} {w}x{h} is not")
            _check_resolution(w, "{size}")
            return ExportLayout((w, w)), notes
        want = max(wtex, htex, 16)
        r = min(4096, 1 << (want - 1).bit_length())
        if r < want:
            notes.append(f"the {wtex} x {htex} texture is sampled on one 4096 alphamap; "
                         "tiles of 4096 (or smaller) keep every texel")
        return ExportLayout((r, r)), notes
    _check_resolution(options.tile, "{tile}")
    return tiled_layout(texture_size, options.tile, options.size), notes


def plan(project: ThematicTexture, options: ExportOptions) -> ExportPlan:
    """Decide the layout and list the files of a Unity export."""
    layout, notes = unity_layout(project.grid.texture_size, options)
    n_splat = -(-len(project.library) // 4)
    files = [f"splatmap_{s}{piece.suffix if layout.tile else ''}.png"
             for piece in layout.pieces() for s in range(n_splat)]
    files += theme_files(project) + list(UNITY_SCRIPTS)
    return map_plan(project, options, layout, files, MANIFEST, notes)


def splatmaps(weights: np.ndarray) -> list[np.ndarray]:
    """``(K, h, w)`` theme weights as ``ceil(K/4)`` RGBA8 images ``(h, w, 4)`` (unused: 0)."""
    k, h, w = weights.shape
    out = []
    for s in range(-(-k // 4)):
        image = np.zeros((h, w, 4), dtype=np.uint8)
        part = weights[4 * s : 4 * s + 4]
        image[:, :, : part.shape[0]] = np.moveaxis(part, 0, 2)
        out.append(image)
    return out


def write(project: ThematicTexture, plan: ExportPlan, folder: Path,
          progress: Progress | None = None) -> None:
    """Write the splatmaps, theme textures, editor script and manifest of ``plan``."""
    layout = plan.layout
    tiles = []
    spacing = pixel_spacing(project, plan)
    tile_world = ((layout.size[0] - 1 if layout.tile is None else layout.tile - 1) * spacing[0],
                  (layout.size[1] - 1 if layout.tile is None else layout.tile - 1) * spacing[1])
    ky = layout.tiles[1]
    for piece, weights in piece_weights(project, plan, progress):
        names = []
        for s, image in enumerate(splatmaps(weights)):
            name = f"splatmap_{s}{piece.suffix if layout.tile else ''}.png"
            write_image(folder / name, image, attributes=STORED_ALPHA)
            names.append(name)
        # Unity's z runs north: tile row 0 (north) is the farthest from the origin.
        tile = {"x": piece.tx, "y": piece.ty, "splatmaps": names,
                "position": [piece.tx * tile_world[0], (ky - 1 - piece.ty) * tile_world[1]]}
        if project.colour_map is not None:
            tile["colour_map_st"] = unity_colour_st(project, layout, piece)
        tiles.append(tile)
    write_shared_files(project, folder)
    for name, source in UNITY_SCRIPTS.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        write_bytes_atomic(folder / name, (_SCRIPTS / source).read_bytes())
    sx, sy = plan.world.texel_size
    layers = []
    for theme, name, texture in zip(project.library, layer_names(project), theme_files(project),
                                    strict=True):
        th, tw = theme.texture.shape[:2]
        size = [tw * sx, th * sy]
        # Unity's v runs up from the tile's south edge; rows of the theme run down from its north.
        layers.append({"name": name, "texture": texture, "tile_size": size,
                       "tile_offset": [0.0, float(-tile_world[1] % size[1])]})
    manifest = common_manifest(project, plan, COLOUR_MAP)
    manifest.update({
        "alphamap_resolution": layout.tile or layout.size[0],
        "map_size": list(layout.size),
        "tiles_x": layout.tiles[0],
        "tiles_y": layout.tiles[1],
        "tile_world_size": list(tile_world),
        "terrain_size": [layout.tiles[0] * tile_world[0], layout.tiles[1] * tile_world[1]],
        "layers": layers,
        "tiles": tiles,
    })
    write_manifest(folder / MANIFEST, manifest)
