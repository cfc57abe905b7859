"""Where coarse pixels lie in their photo: the optional position features.

With ``FeatureOptions.position`` a class prior that depends on the place (a shore
along one edge) is learnt from them (:func:`core.classify.features.with_position`).
"""

from __future__ import annotations

import numpy as np


def position_features(shape: tuple[int, int], origin: tuple[int, int],
                      photo_size: tuple[int, int], scale: int) -> np.ndarray:
    """Row and column of each coarse pixel's centre over the photo's (H, W): (h, w, 2)
    float32, for ``shape`` (h, w) coarse pixels from photo pixel ``origin``."""
    h, w = shape
    rows = (origin[0] + (np.arange(h, dtype=np.float32) + 0.5) * scale) / photo_size[0]
    cols = (origin[1] + (np.arange(w, dtype=np.float32) + 0.5) * scale) / photo_size[1]
    return np.stack(np.broadcast_arrays(rows[:, None], cols[None, :]), axis=2)
