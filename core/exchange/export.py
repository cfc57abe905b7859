"""One export entry point: plan (what will be written, checked before work), then write."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from terratheme.core.exchange import geotiff, terrain3d, unity, unreal
from terratheme.core.exchange.options import Engine, ExportOptions
from terratheme.core.exchange.plan import ExportPlan, write_carried_project
from terratheme.core.exchange.style import export_boundary
from terratheme.core.io.atomic import file_set, missing_folders, remove_empty_folders
from terratheme.core.model.project import ThematicTexture

Progress = Callable[[int, int], None]
_ENGINES = {Engine.UNITY: unity, Engine.UNREAL: unreal, Engine.GODOT: terrain3d,
            Engine.GEOTIFF: geotiff}


def plan_export(project: ThematicTexture, options: ExportOptions) -> ExportPlan:
    """Decide sizes and tiles and list every file of an export; refuses before any work."""
    export_boundary(project, options)
    return _ENGINES[options.engine].plan(project, options)


def write_export(project: ThematicTexture, plan: ExportPlan, folder: str | os.PathLike, *,
                 progress: Progress | None = None) -> list[Path]:
    """Write ``plan``'s files and the project (for ``new --from``) into ``folder`` as one set
    (:func:`core.io.atomic.file_set`); returns the paths written.

    A failed export leaves no file, and no folder it made (empty ones only are removed).
    """
    out = Path(folder)
    paths = plan.paths(out)
    made = missing_folders(paths)
    out.mkdir(parents=True, exist_ok=True)
    try:
        with file_set(paths):
            write_carried_project(project, out)
            _ENGINES[plan.options.engine].write(project, plan, out, progress)
    except BaseException:
        remove_empty_folders(made)
        raise
    return paths
