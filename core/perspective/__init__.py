"""Low-angle terrain preview with anisotropic filtering (issue 6).

The seed's parallelogram filter (Kovalev & Tarasov, DESIGN.md section 3) and
its baselines, all with one set of conventions (see :mod:`.mapping`)::

    from core.perspective import Camera, FilterOptions, Method, PreparedTexture
    prepared = PreparedTexture(texture, FilterOptions(method=Method.PARALLELOGRAM))
    frame = prepared.render(Camera(height=40, pitch=10, yaw=30), (640, 360)).image

Modules: ``options`` (FilterOptions, Method), ``mapping`` (eqs. 1-2, camera),
``footprint`` (eqs. 3-4), ``family`` (the prefiltered copies),
``lookup`` (eqs. 5-9), ``baselines`` (nearest, bilinear, trilinear, GPU
aniso), ``ewa`` (pbrt-style EWA), ``reference`` (supersampled box filter),
``texture`` (power-of-two resampling, mip pyramid), ``render`` (entry points).
"""

from core.perspective.footprint import Footprint, footprint_parameters
from core.perspective.mapping import Camera, PlaneMapping, camera_mapping
from core.perspective.options import FilterOptions, Method
from core.perspective.render import PreparedTexture, RenderResult, render_perspective

__all__ = [
    "Camera",
    "FilterOptions",
    "Footprint",
    "Method",
    "PlaneMapping",
    "PreparedTexture",
    "RenderResult",
    "camera_mapping",
    "footprint_parameters",
    "render_perspective",
]
