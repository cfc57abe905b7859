"""Low-angle terrain preview with anisotropic filtering (design.md §6).

The seed's family of prefiltered parallelogram copies (Kovalev & Tarasov), read by
summing the pixel's own parallelogram over the cells it covers, and its baselines, all
in the conventions of :mod:`.mapping`::

    from terratheme.core.io.disk_cache import DiskCache
    from terratheme.core.perspective import Camera, FilterOptions, PreparedTexture
    prepared = PreparedTexture(texture, FilterOptions(), cache=DiskCache(folder))
    frame = prepared.render(Camera(height=40, pitch=10, yaw=30), (640, 360)).image
"""

from terratheme.core.perspective.flight import Flight, FlightControls, FlightInput, clip_matrix
from terratheme.core.perspective.mapping import (
    MAX_FRAME_SIDE,
    Camera,
    PlaneMapping,
    camera_mapping,
    check_size,
    view_mapping,
)
from terratheme.core.perspective.options import FilterOptions, Method
from terratheme.core.perspective.render import (
    PreparedTexture,
    RenderResult,
    family_key,
    render_perspective,
)

__all__ = [
    "MAX_FRAME_SIDE",
    "Camera",
    "FilterOptions",
    "Flight",
    "FlightControls",
    "FlightInput",
    "Method",
    "PlaneMapping",
    "PreparedTexture",
    "RenderResult",
    "camera_mapping",
    "view_mapping",
    "check_size",
    "clip_matrix",
    "family_key",
    "render_perspective",
]
