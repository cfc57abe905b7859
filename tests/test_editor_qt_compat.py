"""The PySide6 None-refcount guard keeps long Qt sessions alive."""

from __future__ import annotations

import sys

import pytest

pytest.importorskip("PySide6")

pytestmark = pytest.mark.qt


def test_many_void_qt_calls_do_not_exhaust_none():
    from PySide6.QtCore import QObject

    import app.editor  # noqa: F401  (applies the guard)

    obj = QObject()
    # Far more void calls than None had references before the guard (a few thousand).
    start = sys.getrefcount(None)
    for _ in range(200_000):
        obj.setObjectName("x")
    assert sys.getrefcount(None) > 0
    if sys.version_info < (3, 12):
        assert start > 200_000 or sys.getrefcount(None) >= start
