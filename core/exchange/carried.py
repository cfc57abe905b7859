"""The way back from an export: the project it carries (``new --from export``).

Every export writes the project beside its maps (:data:`core.exchange.plan.CARRIED`)
and names it in its manifest. The engine maps are resampled, so the grid, themes and
colour map come back exactly from that file; the manifest's grid and cell must agree.
"""

from __future__ import annotations

import os
from pathlib import Path

from terratheme.core.errors import TerrathemeError
from terratheme.core.io.archive import parse_json, read_bounded
from terratheme.core.io.atomic import special_file
from terratheme.core.model.project import ThematicTexture, load_project

#: a manifest is a few kB (a tiled Unreal export lists every tile): far below this
MAX_MANIFEST_BYTES = 16 << 20
MANIFEST_GLOB = "terratheme_*.json"


def export_manifest(path: str | os.PathLike) -> Path:
    """The manifest of an export given as its folder or its manifest file (TerrathemeError
    for none or several)."""
    p = Path(path)
    if p.is_dir() and p.match(MANIFEST_GLOB):
        raise TerrathemeError(f"{p}: is a folder, not an export manifest")
    if p.is_dir():
        found = sorted(f for f in p.glob(MANIFEST_GLOB) if not f.is_dir())
        if len(found) != 1:
            what = "no" if not found else f"{len(found)}"
            raise TerrathemeError(f"{p}: {what} export manifests ({MANIFEST_GLOB}) in the "
                                  "folder; name the manifest")
        return found[0]
    if not p.is_file():
        kind = special_file(p)
        raise TerrathemeError(f"{p}: is {kind}, not an export manifest" if kind else
                              f"{p}: no such export folder or manifest")
    return p


def carried_project_path(path: str | os.PathLike) -> Path:
    """The project file an export (its folder or manifest at ``path``) names, not read:
    an input, which an output must not replace; TerrathemeError when it names none."""
    return _carried(path)[2]


def _carried(path: str | os.PathLike) -> tuple[Path, dict, Path]:
    """The manifest's path, its checked JSON and the carried project's path."""
    manifest = export_manifest(path)
    data = parse_json(read_bounded(manifest, MAX_MANIFEST_BYTES, str(manifest)), str(manifest))
    if not isinstance(data, dict) or not str(data.get("format", "")).startswith("terratheme-"):
        raise TerrathemeError(f"{manifest}: not a terratheme export manifest")
    name = data.get("project")
    if name is None:
        raise TerrathemeError(f"{manifest}: the export carries no project (written before "
                              "exports carried it): export again, or read its maps with "
                              "--from splatmap, weights or terrain3d")
    if (not isinstance(name, str) or Path(name).name != name or name in ("", ".", "..")
            or not name.isprintable()):  # a NUL would reach the file system as a ValueError
        raise TerrathemeError(f"{manifest}: 'project' must be a file name beside the "
                              f"manifest, not {name!r}")
    return manifest, data, manifest.parent / name


def project_from_export(path: str | os.PathLike) -> ThematicTexture:
    """The project an export carries (its folder or manifest at ``path``); TerrathemeError
    when there is none or its grid or cell is not the manifest's."""
    manifest, data, project_path = _carried(path)
    project = load_project(project_path)
    shape, cell = list(project.grid.indices.shape), list(project.grid.cell)
    if data.get("grid_shape") != shape or data.get("cell") != cell:
        raise TerrathemeError(
            f"{manifest}: the carried project's grid ({shape[1]} x {shape[0]} vertices, cell "
            f"{cell[0]}x{cell[1]}) is not the manifest's ({data.get('grid_shape')}, cell "
            f"{data.get('cell')}): the folder mixes two exports")
    return project
