"""Themes: small tileable textures, how they are made tileable and scored, and cut from photos.

``library`` (themes, shipped set), ``tileable`` and ``seam_cut`` (wrapping, seam score),
``quality`` (repetition scores), ``histogram`` (Gaussianisation), ``from_photo``,
``patch_search``, ``cut_mask`` and ``quilt`` (themes cut from a photo), ``matching`` and
``looks`` (classes to themes), ``detail`` (detail themes under a colour map).
"""

from terratheme.core.themes.from_photo import (
    PatchOptions,
    ThemeMapping,
    themes_by_name,
    themes_from_photo,
)
from terratheme.core.themes.library import (
    SHIPPED_THEMES_DIR,
    Theme,
    ThemeLibrary,
    flat_theme,
    read_theme_library,
    shipped_theme_library,
)
from terratheme.core.themes.looks import read_looks
from terratheme.core.themes.quality import landmark_score, lowfreq_score, repeat_score
from terratheme.core.themes.tileable import (
    SEAM_THRESHOLD,
    TileableOptions,
    make_tileable,
    seam_score,
)

__all__ = [
    "SEAM_THRESHOLD",
    "SHIPPED_THEMES_DIR",
    "PatchOptions",
    "Theme",
    "ThemeLibrary",
    "ThemeMapping",
    "TileableOptions",
    "flat_theme",
    "landmark_score",
    "lowfreq_score",
    "make_tileable",
    "read_looks",
    "read_theme_library",
    "repeat_score",
    "seam_score",
    "shipped_theme_library",
    "themes_by_name",
    "themes_from_photo",
]
