"""Work around a PySide6 reference-count bug that crashes long Qt sessions.

PySide6-Essentials 6.12.0 on CPython 3.11 drops one reference to ``None`` on every
call of a C++ method returning ``void``; after seconds of painting the interpreter
aborts ("Fatal Python error: none_dealloc"). CPython 3.12+ makes ``None`` immortal.
Before it, :func:`guard_none_refcount` tests for the leak once and, if present, gives
``None`` a huge reference count (what 3.12 does; ``None`` is never freed anyway).
"""

from __future__ import annotations

import ctypes
import sys

_applied = False


def void_call_leaks_none() -> bool:
    """True if calling a void Qt method drops references to None (the PySide6 bug)."""
    from PySide6.QtCore import QObject

    probe = QObject()
    before = sys.getrefcount(None)
    for _ in range(64):
        probe.setObjectName("probe")
    return sys.getrefcount(None) < before - 32


def guard_none_refcount() -> bool:
    """Apply the work-around if needed (idempotent); returns whether it is active."""
    global _applied
    if _applied or sys.version_info >= (3, 12):
        return _applied
    if void_call_leaks_none():
        # CPython < 3.12 keeps ob_refcnt as the first Py_ssize_t of every object.
        ctypes.c_ssize_t.from_address(id(None)).value += 1 << 48
        _applied = True
    return _applied
