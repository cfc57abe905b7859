"""Hilbert and Morton space-filling curves over an image (seed sfc_packing.txt, section 1).

Names are loaded on first use, so file readers importing :mod:`core.curves.square` do
not load numba.
"""

from __future__ import annotations

from terratheme.core.curves.square import MAX_SIDE, Curve, curve_order

__all__ = [
    "MAX_SIDE",
    "Curve",
    "curve_order",
    "fill_runs",
    "scan_runs",
]


def __getattr__(name: str) -> object:
    """The numba-backed functions, imported when first asked for (PEP 562)."""
    if name == "scan_runs":
        from terratheme.core.curves import scan

        return getattr(scan, name)
    if name == "fill_runs":
        from terratheme.core.curves.fill import fill_runs

        return fill_runs
    raise AttributeError(f"module 'terratheme.core.curves' has no attribute {name!r}")
