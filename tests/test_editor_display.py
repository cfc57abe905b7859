"""The editor without a usable display: one line and exit 2, not Qt's abort (app.editor.display)."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from terratheme.app.editor import display
from terratheme.app.editor.display import display_problem, prepare_display
from terratheme.core.errors import TerrathemeError

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
                                 {"QT_QPA_PLATFORM": "wayland", "DISPLAY": NO_SERVER}])
def test_platforms_without_an_x_server_are_left_to_qt(env):
    assert display_problem(env) is None


@linux_only
def test_a_wayland_session_is_left_to_qt_and_a_stale_one_to_the_x_checks(tmp_path):
    with socket.socket(socket.AF_UNIX) as server:
        server.bind(str(tmp_path / "wayland-7"))
        env = {"WAYLAND_DISPLAY": "wayland-7", "XDG_RUNTIME_DIR": str(tmp_path)}
        assert display_problem(env) is None
        assert display_problem({"WAYLAND_DISPLAY": str(tmp_path / "wayland-7")}) is None
    # found: a stale WAYLAND_DISPLAY skipped the checks, then Qt aborted on the missing X display
    stale = {"WAYLAND_DISPLAY": "wayland-8", "XDG_RUNTIME_DIR": str(tmp_path)}
    assert "DISPLAY is not set" in display_problem(stale)
    assert "DISPLAY is not set" in display_problem({"WAYLAND_DISPLAY": "wayland-0"})


@pytest.fixture
def x_server():
    """A display number served by a fresh Xvfb over TCP (skips without Xvfb).

    ``-noreset``: by default Xvfb resets when its last client leaves and drops a client that
    connects meanwhile; under load that failed the second check of a test (CI, 12 of 80).
    """
    if not shutil.which("Xvfb"):
        pytest.skip("Xvfb is not installed")
    number = 200 + os.getpid() % 300
    server = subprocess.Popen(["Xvfb", f":{number}", "-screen", "0", "64x64x24", "-nolisten",
                               "unix", "-listen", "tcp", "-nolock", "-noreset"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", 6000 + number), timeout=1).close()
                break
            except OSError:
                if server.poll() is not None:
                    pytest.skip("Xvfb did not start")
                time.sleep(0.1)
        yield f"127.0.0.1:{number}"
    finally:
        server.terminate()
        server.wait(10)


@linux_only
def test_a_running_x_server_passes_and_a_screen_it_lacks_is_named(x_server):
    assert display_problem({"DISPLAY": x_server}) is None
    assert display_problem({"DISPLAY": x_server + ".0"}) is None
    problem = display_problem({"DISPLAY": x_server + ".3"})
    assert problem is not None and x_server + ".3" in problem


@pytest.fixture
def silent_display(monkeypatch):
    """A display (host:number) whose server accepts and never answers; a 0.5 s check timeout."""
    monkeypatch.setattr(display, "CONNECT_TIMEOUT_S", 0.5)
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(1)
        port = silent.getsockname()[1]
        if not 6000 < port < 6000 + 65536:
            pytest.skip("no free port above 6000")
        yield f"127.0.0.1:{port - 6000}"


@linux_only
def test_a_server_that_never_answers_is_named_after_the_timeout(silent_display):
    t0 = time.monotonic()
    problem = display_problem({"DISPLAY": silent_display})
    assert time.monotonic() - t0 < 5
    assert problem == f"the X display {silent_display!r} does not answer within 0.5 s"


@linux_only
def test_a_missing_library_is_named_with_its_package(monkeypatch):
    monkeypatch.setattr(display, "XCB_PACKAGES", {"libterratheme-absent.so.7": "libabsent7",
                                                  **display.XCB_PACKAGES})
    problem = display_problem({"DISPLAY": NO_SERVER})
    assert "libterratheme-absent.so.7" in problem and "apt-get install libabsent7" in problem


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


@linux_only
def test_a_screenshot_past_a_silent_display_forgets_it(monkeypatch, silent_display):
    # found: the offscreen platform's GL still connected to DISPLAY and waited for good
    monkeypatch.delenv("QT_QPA_PLATFORM", raising=False)
    monkeypatch.setenv("DISPLAY", silent_display)
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-stale")
    prepare_display(screenshot=True)
    assert os.environ["QT_QPA_PLATFORM"] == "offscreen"
    assert "DISPLAY" not in os.environ and "WAYLAND_DISPLAY" not in os.environ


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


@linux_only
@pytest.mark.qt
def test_a_screenshot_on_a_real_x_display(tmp_path, x_server):
    shot = tmp_path / "shot.png"
    env = {**_headless_env(), "DISPLAY": x_server, "QT_QPA_PLATFORM": "xcb"}
    done = subprocess.run([sys.executable, "-m", "app", "app", "--screenshot", str(shot),
                           "--size", "640x400"], env=env, cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert shot.stat().st_size > 1000

