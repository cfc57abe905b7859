"""Themes: small tileable textures, how they are made tileable and scored, and cut from photos.

Modules: ``library`` (Theme, ThemeLibrary, the shipped themes), ``tileable``
(periodic-plus-smooth wrap, flattening, crossfade and cut seams; the seam
score), ``quality`` (banding, repetition and landmark scores), ``seam_cut``
(minimum-error boundary cuts), ``histogram`` (Gaussianisation for the
histogram-preserving blend), ``from_photo`` (themes for a classified photo),
``cut_mask`` (what a cut keeps of its window: no other class, border rim or
lone object),
``matching`` (classes to themes by colour and texture), ``looks`` (aerial
exemplars of the shipped themes' classes, for naming), ``detail`` (a theme's
fine detail around its mean, the colour map carrying the rest).
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
