"""Starting points: an empty project, a project over a photo, the bundled sample."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import PROJECT_SUFFIX, ThematicTexture
from terratheme.core.themes.library import ThemeLibrary, flat_theme

SAMPLE_DIR = Path(__file__).resolve().parents[2] / "sample_maps"
DEFAULT_CELL = (16, 16)


def default_library() -> ThemeLibrary:
    """The shipped themes, or a few flat colours when the themes folder is absent."""
    from terratheme.core.themes.library import shipped_theme_library

    try:
        return shipped_theme_library()
    except TerrathemeError:
        return ThemeLibrary([
            flat_theme("grass", (96, 140, 60)), flat_theme("water", (40, 80, 150)),
            flat_theme("sand", (200, 180, 130)), flat_theme("town", (150, 140, 140))])


def empty_project(cells: tuple[int, int] = (64, 64), cell: tuple[int, int] = DEFAULT_CELL
                  ) -> ThematicTexture:
    """A ``cells = (gw, gh)`` grid painted with the first theme."""
    gw, gh = cells
    return ThematicTexture(IndexGrid(np.zeros((gh + 1, gw + 1), dtype=np.uint8), cell),
                           default_library(), {"created_by": "terratheme app"})


def project_from_photo(path: str | Path, cell: tuple[int, int] = DEFAULT_CELL) -> ThematicTexture:
    """A one-theme project covering the photo at ``path`` 1:1 (classify it afterwards)."""
    from terratheme.core.convert.labels_to_grid import grid_shape_for
    from terratheme.core.io.images import Bands, read_image

    photo = read_image(path, dtype=np.uint8, bands=Bands.PHOTO)
    if photo.shape[2] <= 2:  # grey, or grey + alpha (the editor shows the photo opaque)
        photo = np.repeat(photo[..., :1], 3, axis=2)
    photo = np.ascontiguousarray(photo[..., :3])
    rows, cols = grid_shape_for(photo.shape[1], photo.shape[0], cell)
    lib = default_library()
    return ThematicTexture(IndexGrid(np.zeros((rows, cols), dtype=np.uint8), cell), lib,
                           {"source_photo": str(path), "created_by": "terratheme app"},
                           photo=photo)


def sample_project_path() -> Path | None:
    """The first bundled sample project in ``sample_maps/``, if any."""
    if SAMPLE_DIR.is_dir():
        for p in sorted(SAMPLE_DIR.glob(f"*{PROJECT_SUFFIX}")):
            return p
    return None

