"""Godot Terrain3D: its control map (texture ids and blend per vertex) and a texture list.

One 32-bit unsigned integer per terrain vertex (TokisanGames/Terrain3D,
``doc/docs/controlmap_format.md``, commit fc7a744), stored as the bits of a
``FORMAT_RF`` float in a one-channel ``R`` EXR. Bits, from the top::

    31-27  base texture id      (x & 0x1F) << 27
    26-22  overlay texture id   (x & 0x1F) << 22
    21-14  texture blend 0-255  (x & 0xFF) << 14   overlay weight = blend / 255
    13-10  UV angle             (x & 0xF)  << 10
     9-7   UV scale             (x & 0x7)  << 7
     6-3   reserved
     2     hole                 (x & 1) << 2
     1     navigation           (x & 1) << 1
     0     autoshader           x & 1

Each vertex (or ``--size`` pixel) gets its two strongest themes and their renormalised
share, autoshader off. The colour map and ``albedo_color``: docs/engines.md.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import OpenImageIO as oiio
from terratheme.core.errors import OptionError, TerrathemeError
from terratheme.core.exchange.colour import gain_at_pixels, linear_gain
from terratheme.core.exchange.layout import ExportLayout, world_frame
from terratheme.core.exchange.options import ExportOptions
from terratheme.core.exchange.plan import (
    CARRIED,
    STORED_ALPHA,
    ExportPlan,
    common_manifest,
    pixel_spacing,
    theme_files,
    write_manifest,
    write_theme_textures,
)
from terratheme.core.exchange.style import map_slots
from terratheme.core.exchange.weights import BAND_PIXELS, strongest_two
from terratheme.core.io.atomic import atomic_path
from terratheme.core.io.images import write_image, write_oiio
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.rules import cell_splits

#: texture ids a control map holds (5 bits)
MAX_TEXTURES = 32
CONTROL_MAP = "terrain3d_control.exr"
COLOUR_MAP = "terrain3d_colour.png"
#: the colour map's alpha: Terrain3D's neutral roughness modifier (0.5)
NEUTRAL_ROUGHNESS = 128
MANIFEST = "terratheme_godot.json"
#: what a control map of one vertex per grid vertex carries of the borders
VERTEX_BORDERS = "vertex themes only (Terrain3D blends between vertices)"
_REGION_SIZES = tuple(1 << k for k in range(6, 12))
Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class ControlFields:
    """A decoded control map: every field as an ``(H, W)`` uint8 array."""

    base: np.ndarray
    overlay: np.ndarray
    blend: np.ndarray
    uv_angle: np.ndarray
    uv_scale: np.ndarray
    hole: np.ndarray
    navigation: np.ndarray
    autoshader: np.ndarray


def encode_control(base: np.ndarray, overlay: np.ndarray, blend: np.ndarray) -> np.ndarray:
    """(H, W) uint32 control values ``enc_base | enc_overlay | enc_blend`` of ids 0..31 and
    blend 0..255 (overlay weight x 255), autoshader off."""
    base, overlay, blend = (np.asarray(v, dtype=np.uint32) for v in (base, overlay, blend))
    return ((base & 0x1F) << 27) | ((overlay & 0x1F) << 22) | ((blend & 0xFF) << 14)


def decode_control(control: np.ndarray) -> ControlFields:
    """Split ``(H, W)`` uint32 control values into Terrain3D's fields (``get_base`` ...)."""
    c = np.asarray(control, dtype=np.uint32)

    def field(shift: int, mask: int) -> np.ndarray:
        return ((c >> shift) & mask).astype(np.uint8)

    return ControlFields(field(27, 0x1F), field(22, 0x1F), field(14, 0xFF), field(10, 0xF),
                         field(7, 0x7), field(2, 1), field(1, 1), field(0, 1))


def control_labels(control: np.ndarray) -> np.ndarray:
    """The stronger of base and overlay at every pixel (overlay when ``blend > 127``)."""
    f = decode_control(control)
    return np.where(f.blend > 127, f.overlay, f.base).astype(np.uint8)


def write_control_map(path: str | Path, control: np.ndarray) -> None:
    """Write uint32 control values as a one-channel ``R`` 32-bit float EXR, bits untouched
    (``write_image`` would name it ``Y``, which Godot loads as RGB)."""
    values = np.ascontiguousarray(control, dtype=np.uint32)
    h, w = values.shape
    spec = oiio.ImageSpec(w, h, 1, oiio.FLOAT)
    spec.channelnames = ("R",)
    spec.attribute("compression", "zip")
    with atomic_path(path) as tmp:
        write_oiio(path, tmp, spec, values.view(np.float32)[:, :, None])


def terrain3d_layout(grid_shape: tuple[int, int], texture_size: tuple[int, int],
                     texel_size: tuple[float, float], options: ExportOptions) -> ExportLayout:
    """One control map: one pixel per grid vertex by default, or ``size``; never tiled."""
    if options.tile is not None:
        raise OptionError("Terrain3D cuts one control map into regions itself on import: "
                          "export it without {tile}")
    size = options.size or (grid_shape[1], grid_shape[0])
    layout = ExportLayout(size)
    # Terrain3D has one vertex spacing for both axes.
    (wtex, htex), (sx, sy) = texture_size, texel_size
    gx, gy = wtex * sx / (size[0] - 1), htex * sy / (size[1] - 1)
    if abs(gx - gy) > 1e-6 * max(gx, gy):
        raise OptionError(
            f"a {size[0]} x {size[1]} control map spaces its vertices {gx:.6g} x {gy:.6g} apart; "
            "Terrain3D needs one vertex spacing: pick {size} with (W - 1) : (H - 1) = "
            f"{wtex * sx:.6g} : {htex * sy:.6g}")
    return layout


def plan(project: ThematicTexture, options: ExportOptions) -> ExportPlan:
    """Decide the control map size and list the files of a Terrain3D export."""
    k = len(project.library)
    if k > MAX_TEXTURES:
        raise TerrathemeError(f"Terrain3D holds {MAX_TEXTURES} textures; "
                              f"the project has {k} themes")
    world = world_frame(project.metadata.get("georeference"), project.grid.texture_size)
    layout = terrain3d_layout(project.grid.indices.shape, project.grid.texture_size,
                              world.texel_size, options)
    notes = []
    sizes = {t.texture.shape[:2] for t in project.library}
    if len(sizes) > 1:
        notes.append("Terrain3D needs textures of one size: themes resampled to "
                     f"{max(s[1] for s in sizes)} x {max(s[0] for s in sizes)} "
                     "(uv_scale keeps their world size)")
    wtex, htex = project.grid.texture_size
    spacing = wtex / (layout.size[0] - 1)
    if project.colour_map is not None and spacing > project.colour_map.scale:
        notes.append(f"the colour map (a pixel per {project.colour_map.scale} texels) is sampled "
                     f"at the control map's vertices (one per {spacing:g} texels); "
                     f"a {wtex + 1} x {htex + 1} map keeps it (a vertex per texel)")
    borders = None
    gh, gw = project.grid.indices.shape
    if layout.size == (gw, gh):
        # A vertex per grid vertex: each holds its theme alone, blend 0.
        borders = VERTEX_BORDERS
        notes.append(f"one control-map vertex per grid vertex: each holds its own theme (blend "
                     f"0) and Terrain3D blends between vertices, with neither the diagonal "
                     f"split nor shaped borders; --size {wtex + 1}x{htex + 1} (a vertex per "
                     "texel) carries the borders' two strongest themes and their blend")
    colour = () if project.colour_map is None else (COLOUR_MAP,)
    files = (CONTROL_MAP, *colour, *theme_files(project), CARRIED, MANIFEST)
    return ExportPlan(options, layout, world, files, tuple(notes), borders)


def control_map(project: ThematicTexture, size: tuple[int, int], options: ExportOptions
                ) -> np.ndarray:
    """The ``(H, W)`` uint32 control values of a map of ``size`` over the project's grid."""
    w, h = size
    splits = cell_splits(project.grid.indices, options.saddle)
    out = np.empty((h, w), dtype=np.uint32)
    rows = max(1, BAND_PIXELS // w)
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        slots = map_slots(project, size, (0, r0, w, r1 - r0), options, splits=splits)
        out[r0:r1] = encode_control(*strongest_two(slots))
    return out


def colour_map_image(project: ThematicTexture, size: tuple[int, int]) -> np.ndarray:
    """``(H, W, 4)`` uint8 Terrain3D colour map: the gain at each vertex, neutral roughness."""
    w, h = size
    image = np.full((h, w, 4), NEUTRAL_ROUGHNESS, dtype=np.uint8)
    image[:, :, :3] = gain_at_pixels(project.colour_map, project.grid.texture_size, size)
    return image


def write(project: ThematicTexture, plan: ExportPlan, folder: Path,
          progress: Progress | None = None) -> None:
    """Write the control map, the theme textures (one size) and the texture list of ``plan``."""
    layout = plan.layout
    write_control_map(folder / CONTROL_MAP, control_map(project, layout.size, plan.options))
    if project.colour_map is not None:
        write_image(folder / COLOUR_MAP, colour_map_image(project, layout.size),
                    attributes=STORED_ALPHA)
    if progress:
        progress(1, 2)
    tw = max(t.texture.shape[1] for t in project.library)
    th = max(t.texture.shape[0] for t in project.library)
    # Terrain3D's texture arrays need one size: smaller themes are resampled up.
    textures = [t.texture if t.texture.shape[:2] == (th, tw)
                else cv2.resize(t.texture, (tw, th), interpolation=cv2.INTER_CUBIC)
                for t in project.library]
    write_theme_textures(project, folder, textures)
    spacing = pixel_spacing(project, plan)[0]
    w, h = layout.size
    # Terrain3D has 32 x 32 regions: the smallest region holding the map centred on the origin.
    region = next((r for r in _REGION_SIZES if 32 * r >= max(w, h)), None)
    if region is None:
        raise TerrathemeError(f"a {w} x {h} control map exceeds Terrain3D's 65536-vertex world")
    # The importer's import_position is the map's top-left corner in vertices (descaled).
    corner = [-(-(w // 2) // region) * region, -(-(h // 2) // region) * region]
    sx = plan.world.texel_size[0]
    manifest = common_manifest(project, plan, None if project.colour_map is None else COLOUR_MAP)
    if plan.borders is not None:
        manifest.update({"borders": "vertex", "boundary": None})
    tint = [1.0] * 3 if project.colour_map is None else [linear_gain()] * 3
    manifest.update({
        "control_map": CONTROL_MAP,
        "control_map_size": [w, h],
        "vertex_spacing": spacing,
        "region_size": region,
        "import_position": [-corner[0], -corner[1]],
        # Terrain3D repeats a texture every 1 / uv_scale world units.
        # albedo_color brings the colour map's neutral 128 to 1 (docs/engines.md).
        "textures": [{"id": j, "name": t.name, "albedo": f, "albedo_color": tint,
                      "uv_scale": 1.0 / (t.texture.shape[1] * sx)}
                     for j, (t, f) in enumerate(zip(project.library, theme_files(project),
                                                    strict=True))],
    })
    write_manifest(folder / MANIFEST, manifest)
    if progress:
        progress(2, 2)
