"""The editor without a usable display: one line and exit 2, not Qt's abort (app.editor.display)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from app.editor.display import display_problem, prepare_display
from core.errors import TerrathemeError

ROOT = Path(__file__).resolve().parents[1]
linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the X11 checks run on Linux only")
#: a display number no X server listens on
NO_SERVER = ":48611"


@linux_only
def test_no_display_variable_is_named():
    assert "DISPLAY is not set" in display_problem({})
    assert "DISPLAY is not set" in display_problem({"QT_QPA_PLATFORM": "xcb"})


@linux_only
def test_a_display_nobody_answers_is_named():
    problem = display_problem({"DISPLAY": NO_SERVER})
    assert problem is not None
    assert NO_SERVER in problem or "system library" in problem


@pytest.mark.parametrize("env", [{"QT_QPA_PLATFORM": "offscreen"},
                                 {"QT_QPA_PLATFORM": "minimal:enable_fonts"},
                                 {"WAYLAND_DISPLAY": "wayland-0"},
                                 {"QT_QPA_PLATFORM": "wayland", "DISPLAY": NO_SERVER}])
def test_platforms_without_an_x_server_are_left_to_qt(env):
    assert display_problem(env) is None


@linux_only
@pytest.mark.skipif(not os.environ.get("DISPLAY"), reason="no X display in this environment")
def test_a_running_x_server_passes():
    if os.environ.get("QT_QPA_PLATFORM", "xcb").split(":")[0] not in ("", "xcb"):
        pytest.skip("tests run on a headless Qt platform")
    assert display_problem(os.environ) is None


@linux_only
def test_prepare_raises_for_the_window_and_goes_offscreen_for_a_screenshot(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.delenv("QT_QPA_PLATFORM", raising=False)
    with pytest.raises(TerrathemeError, match="DISPLAY is not set"):
        prepare_display(screenshot=False)
    assert "QT_QPA_PLATFORM" not in os.environ
    prepare_display(screenshot=True)
    assert os.environ["QT_QPA_PLATFORM"] == "offscreen"


def _headless_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    env["PYTHONPATH"] = str(ROOT)
    return env


@linux_only
def test_the_app_command_without_a_display_is_one_line(tmp_path):
    done = subprocess.run([sys.executable, "-m", "app", "app", "--no-classify"],
                          env=_headless_env(), cwd=tmp_path, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "DISPLAY is not set" in lines[0]
    assert "Traceback" not in done.stderr and "qt.qpa" not in done.stderr


@linux_only
@pytest.mark.qt
def test_a_screenshot_without_a_display_is_drawn_offscreen(tmp_path):
    shot = tmp_path / "shot.png"
    done = subprocess.run([sys.executable, "-m", "app", "app", "--screenshot", str(shot),
                           "--size", "640x400"], env=_headless_env(), cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert shot.stat().st_size > 1000
