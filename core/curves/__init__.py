"""Hilbert and Morton space-filling curves over an image (seed sfc_packing.txt, section 1).

Modules: ``steps`` (the curves: scalar numba functions, array functions over
them, texel <-> step in image coordinates, the block plan of a scan), ``scan``
(whole-image scans along a curve: runs, fill, order, ranks).
"""

from core.curves.scan import fill_runs, scan_order, scan_runs
from core.curves.steps import MAX_SIDE, Curve, curve_order, step_table, steps_of, texels_of

__all__ = [
    "MAX_SIDE",
    "Curve",
    "curve_order",
    "fill_runs",
    "scan_order",
    "scan_runs",
    "step_table",
    "steps_of",
    "texels_of",
]
