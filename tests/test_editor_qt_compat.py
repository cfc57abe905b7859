"""The PySide6 None-refcount guard: applied only where void Qt calls leak references to None."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytest.importorskip("PySide6")

pytestmark = pytest.mark.qt


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    return out.stdout.strip()


@pytest.mark.skipif(sys.version_info >= (3, 12), reason="None is immortal from Python 3.12")
def test_a_leaking_build_gets_none_a_huge_count():
    # The guard adds 2^48; other references to None come and go meanwhile (one fewer
    # made it 2^48 - 1 in a clean clone), so half of that is asked for.
    got = _run(
        "import sys\n"
        "import terratheme.app.editor.qt_compat as q\n"
        "q._applied = False\n"
        "q.void_call_leaks_none = lambda: True\n"
        "before = sys.getrefcount(None)\n"
        "print(q.guard_none_refcount(), sys.getrefcount(None) - before >= 1 << 47)\n"
    )
    assert got == "True True"


def test_a_sound_build_is_left_alone():
    got = _run(
        "import sys\n"
        "import terratheme.app.editor.qt_compat as q\n"
        "q._applied = False\n"
        "q.void_call_leaks_none = lambda: False\n"
        "before = sys.getrefcount(None)\n"
        "print(q.guard_none_refcount(), abs(sys.getrefcount(None) - before) < 1000)\n"
    )
    assert got == "False True"


def test_many_void_calls_do_not_abort_the_interpreter():
    # On a leaking build without the guard, None's count reaches zero long before
    # 200,000 void calls and the process aborts ("none_dealloc"): check=True fails then.
    got = _run(
        "from PySide6.QtCore import QObject\n"
        "import terratheme.app.editor\n"
        "obj = QObject()\n"
        "for _ in range(200_000):\n"
        "    obj.setObjectName('x')\n"
        "print('alive')\n"
    )
    assert got == "alive"
