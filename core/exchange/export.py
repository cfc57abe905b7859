"""One export entry point: plan (what will be written, checked before work), then write."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from terratheme.core.exchange import geotiff, terrain3d, unity, unreal
from terratheme.core.exchange.options import Engine, ExportOptions
from terratheme.core.exchange.plan import ExportPlan, write_carried_project
from terratheme.core.exchange.style import export_boundary
from terratheme.core.io.atomic import file_set
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
    made = [d for d in (out, *out.parents) if not os.path.lexists(d)]
    had = _folders(out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        with file_set(plan.paths(out)):
            write_carried_project(project, out)
            _ENGINES[plan.options.engine].write(project, plan, out, progress)
    except BaseException:
        # Deepest first: the engine's subfolders, then the export folder and its parents.
        for d in sorted(_folders(out) - had, key=lambda p: len(p.parts), reverse=True) + made:
            try:
                d.rmdir()
            except OSError:
                pass
        raise
    return plan.paths(out)


def _folders(root: Path) -> set[Path]:
    """The folders under ``root`` (itself included; links not followed), none if it is none."""
    if not root.is_dir() or root.is_symlink():
        return set()
    return {root, *(Path(top) / d for top, dirs, _ in os.walk(root) for d in dirs)}
