"""Unreal Engine landscape: one 8-bit weight map per theme, a flat heightmap, theme textures.

Sizes are Epic's recommended landscape sizes (127 .. 8129 vertices); each vertex's weights
sum to 255; a flat 16-bit heightmap (32768) comes along for "Import from File"; tiles use
Unreal's ``name_x0_y0.png`` naming and share border vertices. The colour map ships with its
vertex-to-UV transform and :data:`MATERIAL_SCRIPT` builds the material (docs/engines.md).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from terratheme.core.errors import OptionError, TerrathemeError
from terratheme.core.exchange import plan as export_plan
from terratheme.core.exchange.colour import COLOUR_MAP, vertex_colour_uv
from terratheme.core.exchange.layout import ExportLayout, tiled_layout
from terratheme.core.exchange.options import ExportOptions
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.io.images import write_image
from terratheme.core.model.project import ThematicTexture

#: Epic's recommended landscape sizes (vertices per side) and their component size in quads
UNREAL_SIZES = {127: 126, 253: 126, 505: 126, 1009: 126, 2017: 126, 4033: 126, 8129: 254}
#: heightmap value of height 0 (Unreal's 16-bit heights are centred on 32768)
FLAT_HEIGHT = 32768
MANIFEST = "terratheme_unreal.json"
#: the editor script that builds the landscape material (Unreal's Python), as the export names it
MATERIAL_SCRIPT = "terratheme_unreal_material.py"
_SCRIPT_SOURCE = Path(__file__).resolve().parent / "scripts" / MATERIAL_SCRIPT
Progress = Callable[[int, int], None]


def _check_size(n: int, what: str) -> None:
    """``what``: the option, as an :class:`OptionError` template (``{tile}``)."""
    if n not in UNREAL_SIZES:
        raise OptionError(f"{what} {n} is not a recommended Unreal landscape size "
                          f"({', '.join(map(str, UNREAL_SIZES))} vertices)")


def _fit(n: int) -> int:
    """The smallest recommended size of at least ``n`` vertices (the largest if none)."""
    return next((s for s in UNREAL_SIZES if s >= n), max(UNREAL_SIZES))


def unreal_layout(texture_size: tuple[int, int], options: ExportOptions
                  ) -> tuple[ExportLayout, list[str]]:
    """The weight-map layout of an export, and notes for the user.

    Untiled: each side a recommended size (both with the same component
    size), by default the smallest holding one vertex per texel. Tiled: tiles
    of a recommended size, the whole map ``k * (T - 1) + 1`` vertices each way.
    """
    wtex, htex = texture_size
    notes = []
    if options.tile is None:
        if options.size is not None:
            w, h = options.size
            _check_size(w, "{size} width")
            _check_size(h, "{size} height")
        else:
            w, h = _fit(wtex + 1), _fit(htex + 1)
            if max(w, h) < max(wtex, htex) + 1:
                notes.append(f"the {wtex} x {htex} texture is sampled on an 8129 landscape; "
                             "a tiled export keeps every texel")
        if UNREAL_SIZES[w] != UNREAL_SIZES[h]:
            if options.size is not None:
                raise TerrathemeError(f"a {w} x {h} landscape mixes component sizes "
                                      f"({UNREAL_SIZES[w]} and {UNREAL_SIZES[h]} quads)")
            w = h = max(w, h)
        return ExportLayout((w, h)), notes
    _check_size(options.tile, "{tile}")
    return tiled_layout(texture_size, options.tile, options.size), notes


def weight_file(project: ThematicTexture, k: int, suffix: str = "") -> str:
    """``weight_KK_name[_xI_yJ].png``: the weight map of theme ``k``."""
    return f"weight_{k:02d}_{export_plan.safe_name(project.library[k].name)}{suffix}.png"


def plan(project: ThematicTexture, options: ExportOptions) -> export_plan.ExportPlan:
    """Decide the layout and list the files of an Unreal export."""
    layout, notes = unreal_layout(project.grid.texture_size, options)
    files = []
    for piece in layout.pieces():
        suffix = piece.suffix if layout.tile else ""
        files.append(f"heightmap{suffix}.png")
        files += [weight_file(project, k, suffix) for k in range(len(project.library))]
    files += [*export_plan.theme_files(project), MATERIAL_SCRIPT]
    return export_plan.map_plan(project, options, layout, files, MANIFEST, notes)


def write(project: ThematicTexture, plan: export_plan.ExportPlan, folder: Path,
          progress: Progress | None = None) -> None:
    """Write the heightmaps, weight maps, theme textures and manifest of ``plan``."""
    layout = plan.layout
    k = len(project.library)
    for piece, weights in export_plan.piece_weights(project, plan, progress):
        suffix = piece.suffix if layout.tile else ""
        write_image(folder / f"heightmap{suffix}.png",
                    np.full((piece.h, piece.w, 1), FLAT_HEIGHT, dtype=np.uint16))
        for t in range(k):
            write_image(folder / weight_file(project, t, suffix), weights[t][:, :, None])
    export_plan.write_shared_files(project, folder)
    write_bytes_atomic(folder / MATERIAL_SCRIPT, _SCRIPT_SOURCE.read_bytes())
    # Unreal's landscape scale is centimetres per quad (100 = 1 m between vertices).
    spacing = export_plan.pixel_spacing(project, plan)
    sx, sy = plan.world.texel_size
    # LandscapeLayerCoords' Mapping Scale: landscape quads per repeat of the theme.
    layers = [{"name": name, "weightmap": weight_file(project, j),
               "texture": tex, "texture_world_size_cm": [t.texture.shape[1] * sx * 100,
                                                         t.texture.shape[0] * sy * 100],
               "mapping_scale": t.texture.shape[1] * sx / spacing[0]}
              for j, (t, name, tex) in enumerate(zip(
                  project.library, export_plan.layer_names(project),
                  export_plan.theme_files(project), strict=True))]
    quads = UNREAL_SIZES.get(layout.tile or layout.size[0])
    manifest = export_plan.common_manifest(project, plan, COLOUR_MAP)
    if project.colour_map is not None:
        manifest["colour_map"].update(vertex_colour_uv(project, layout))
    manifest.update({
        "landscape_size": list(layout.size),
        "tile_size": layout.tile,
        "tiles_x": layout.tiles[0],
        "tiles_y": layout.tiles[1],
        "component_quads": quads,
        "section_quads": None if quads is None else quads // 2,
        "sections_per_component": "2x2",
        "landscape_scale_cm": [spacing[0] * 100, spacing[1] * 100, 100.0],
        "heightmap": "heightmap.png" if layout.tile is None else "heightmap_x0_y0.png",
        "flat_height": FLAT_HEIGHT,
        "layers": layers,
    })
    export_plan.write_manifest(folder / MANIFEST, manifest)
