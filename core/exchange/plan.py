"""What an export will write, known before any work starts, and the parts every engine shares.

An :class:`ExportPlan` lists every file, so the caller checks the outputs before the
long work; theme textures and the JSON manifest are written alike for every engine.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange.colour import COLOUR_MAP, colour_manifest, write_colour_map
from terratheme.core.exchange.layout import ExportLayout, TilePiece, WorldFrame, world_frame
from terratheme.core.exchange.options import ExportOptions
from terratheme.core.exchange.style import export_boundary, map_weights
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.io.images import write_image
from terratheme.core.model.project import ThematicTexture, save_project


@dataclass(frozen=True)
class ExportPlan:
    """Everything an export decides before writing.

    ``layout``: the weight/control map and its tiles (None for GIS); ``files``: every file
    relative to the output folder, the manifest last (its presence means the export is
    whole); ``notes``: what to tell the user; ``borders``: what the maps carry of the borders
    when it is not the style's.
    """

    options: ExportOptions
    layout: ExportLayout | None
    world: WorldFrame
    files: tuple[str, ...]
    notes: tuple[str, ...] = field(default=())
    borders: str | None = None

    def paths(self, folder: str | os.PathLike) -> list[Path]:
        """The files under ``folder``."""
        return [Path(folder) / f for f in self.files]


#: the project as exported, without photo and scribbles: what ``new --from export`` reads
#: back (resampled maps need not hold the vertex grid in whole pixels)
CARRIED = "terratheme_project.ttproj"


def map_plan(project: ThematicTexture, options: ExportOptions, layout: ExportLayout,
             files: list[str], manifest: str, notes: list[str]) -> ExportPlan:
    """The plan of a map export: ``files``, the colour map if any, :data:`CARRIED`, then the
    ``manifest``, in the project's world frame."""
    colour = [COLOUR_MAP] if project.colour_map is not None else []
    world = world_frame(project.metadata.get("georeference"), project.grid.texture_size)
    return ExportPlan(options, layout, world, (*files, *colour, CARRIED, manifest),
                      tuple(notes))


def write_carried_project(project: ThematicTexture, folder: Path) -> None:
    """The project without its photo and scribbles, as :data:`CARRIED` in ``folder``."""
    save_project(folder / CARRIED, replace(project, photo=None, scribbles=None))


#: longest theme name in an export's file names (a project's may be 4096 characters; a
#: file name is at most 255 bytes)
MAX_SAFE_NAME = 64


def safe_name(name: str) -> str:
    """A theme name as a file- and engine-safe identifier (letters, digits, ``_``; at most
    :data:`MAX_SAFE_NAME` characters)."""
    safe = re.sub(r"[^A-Za-z0-9_]+", "_", name.strip()).strip("_")[:MAX_SAFE_NAME]
    return safe.rstrip("_") or "theme"


def layer_names(project: ThematicTexture) -> list[str]:
    """Each theme's :func:`safe_name`, made distinct (an engine names one asset per layer):
    a name already taken gets its theme's index, ``_KK``, appended."""
    names: list[str] = []
    for k, theme in enumerate(project.library):
        name = safe_name(theme.name)
        while name in names:
            name += f"_{k:02d}"
        names.append(name)
    return names


def theme_files(project: ThematicTexture) -> list[str]:
    """``theme_KK_name.png``: one texture file per theme, in index order."""
    return [f"theme_{k:02d}_{safe_name(t.name)}.png" for k, t in enumerate(project.library)]


def write_theme_textures(project: ThematicTexture, folder: Path,
                         textures: list[np.ndarray] | None = None) -> None:
    """Write every theme texture as PNG (``textures`` replaces the project's when given)."""
    texs = textures if textures is not None else project.library.textures
    for name, tex in zip(theme_files(project), texs, strict=True):
        write_image(folder / name, tex)


def write_shared_files(project: ThematicTexture, folder: Path) -> None:
    """Write the theme textures and, when the project has one, the colour map."""
    write_theme_textures(project, folder)
    if project.colour_map is not None:
        write_colour_map(folder / COLOUR_MAP, project.colour_map)


def piece_weights(project: ThematicTexture, plan: ExportPlan,
                  progress: Callable[[int, int], None] | None = None
                  ) -> Iterator[tuple[TilePiece, np.ndarray]]:
    """Every tile of ``plan``'s map with its ``(K, h, w)`` theme weights, taken at its own
    pixels of the whole map so shared borders agree; ``progress(done, total)`` after each."""
    layout = plan.layout
    pieces = layout.pieces()
    for i, piece in enumerate(pieces):
        yield piece, map_weights(project, layout.size, (piece.x, piece.y, piece.w, piece.h),
                                 plan.options)
        if progress:
            progress(i + 1, len(pieces))


def write_manifest(path: Path, manifest: dict) -> None:
    """Write an export's JSON manifest atomically; TerrathemeError for a number JSON
    cannot hold (an infinity from a huge georeference), which no reader could load."""
    try:
        text = json.dumps(manifest, indent=1, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise TerrathemeError(f"{path}: export description is not JSON-serialisable ({exc}; "
                              "a georeference too large for the engine's units?)") from None
    write_bytes_atomic(path, (text + "\n").encode())


#: PNG alpha is stored unassociated: OpenImageIO must neither divide nor multiply colour by it
STORED_ALPHA = {"oiio:UnassociatedAlpha": 1}


def common_manifest(project: ThematicTexture, plan: ExportPlan,
                    colour_file: str | None = None) -> dict:
    """The manifest fields every engine shares: grid, cell, world units, style, colour map."""
    world = plan.world
    boundary = export_boundary(project, plan.options)
    return {
        "format": f"terratheme-{plan.options.engine.value}",
        "version": 1,
        "grid_shape": list(project.grid.indices.shape),
        "cell": list(project.grid.cell),
        "texture_size": list(project.grid.texture_size),
        "units": world.units,
        "texel_size": list(world.texel_size),
        "origin": list(world.origin),
        "crs_units": world.crs_units,
        "rotation_deg": world.rotation_deg,
        "borders": "linear" if boundary is None else "shaped",
        "boundary": None if boundary is None else asdict(boundary),
        "colour_map": colour_manifest(project, colour_file),
        "project": CARRIED,
    }


def pixel_spacing(project: ThematicTexture, plan: ExportPlan) -> tuple[float, float]:
    """World units between neighbouring map pixels along x and y."""
    wtex, htex = project.grid.texture_size
    w, h = plan.layout.size
    sx, sy = plan.world.texel_size
    return wtex * sx / (w - 1), htex * sy / (h - 1)
