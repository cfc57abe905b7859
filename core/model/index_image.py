"""Index images: vertex grids stored as pictures, and projects made from them.

One pixel per grid vertex: a grey value is the theme index; a colour (3 or 4 channels)
must be a theme's display colour within ``COLOUR_TOLERANCE`` per channel (a lossy
save survives), any other colour is an error naming it and where.
"""

from __future__ import annotations

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid, validate_indices
from terratheme.core.model.project import ThematicTexture
from terratheme.core.themes.library import ThemeLibrary

COLOUR_TOLERANCE = 12


def indices_from_image(image: np.ndarray, library: ThemeLibrary) -> np.ndarray:
    """(H, W) uint8 vertex indices of an (H, W[, C]) index image for ``library``'s themes.

    C = 1 or 2 holds indices, 3 or 4 display colours (alpha ignored).
    """
    img = np.asarray(image)
    if img.ndim == 2:
        img = img[:, :, None]
    if img.ndim != 3 or img.shape[2] not in (1, 2, 3, 4):
        raise TerrathemeError(f"index image must be (H, W) or (H, W, C), got shape {img.shape}")
    if img.shape[2] in (1, 2):
        return validate_indices(img[:, :, 0], n_themes=len(library))
    if img.dtype != np.uint8:
        raise TerrathemeError(f"colour index image must be 8-bit, got {img.dtype}")
    rgb = img[:, :, :3].astype(np.int16)
    colours = library.colours.astype(np.int16)
    # Nearest display colour (Chebyshev distance) per pixel, then the tolerance check.
    dist = np.abs(rgb[:, :, None, :] - colours[None, None, :, :]).max(axis=3)
    best = dist.argmin(axis=2)
    bad = dist.min(axis=2) > COLOUR_TOLERANCE
    if bad.any():
        y, x = np.argwhere(bad)[0]
        raise TerrathemeError(
            f"index image colour {tuple(int(v) for v in rgb[y, x])} at x={x} y={y} is not the "
            f"display colour of any chosen theme ({', '.join(library.names)}); "
            f"{int(bad.sum())} pixels have unknown colours"
        )
    return validate_indices(best.astype(np.uint8), n_themes=len(library))


def project_from_index_image(
    image: np.ndarray, library: ThemeLibrary, cell: tuple[int, int], metadata: dict | None = None
) -> ThematicTexture:
    """A :class:`ThematicTexture` from an index image (see :func:`indices_from_image`)."""
    indices = indices_from_image(image, library)
    return ThematicTexture(IndexGrid(indices, cell), library, dict(metadata or {}))
