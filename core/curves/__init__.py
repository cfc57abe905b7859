"""Hilbert and Morton space-filling curves over an image (seed sfc_packing.txt, section 1).

Names are loaded on first use, so file readers importing :mod:`core.curves.square` do
not load numba.
"""

from __future__ import annotations

from importlib import import_module

from terratheme.core.curves.square import MAX_SIDE, Curve, curve_order

__all__ = [
    "MAX_SIDE",
    "Curve",
    "curve_order",
    "fill_runs",
    "scan_runs",
]


#: the numba-backed functions and their modules
_LAZY = {"fill_runs": "fill", "scan_runs": "scan"}


def __getattr__(name: str) -> object:
    """The numba-backed functions, imported when first asked for (PEP 562)."""
    if name not in _LAZY:
        raise AttributeError(f"module 'terratheme.core.curves' has no attribute {name!r}")
    return getattr(import_module(f"terratheme.core.curves.{_LAZY[name]}"), name)
