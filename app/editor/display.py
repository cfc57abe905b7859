"""Whether Qt can open a window here, checked before Qt is started.

Qt aborts (exit 134, a page of plugin hints) when its platform plugin cannot start, so
the editor checks the display, the X server and the xcb plugin's libraries first and
prints one line (exit 2). A screenshot without a display is drawn offscreen.
"""

from __future__ import annotations

import os
import re
import sys
import threading
from collections.abc import Mapping
from pathlib import Path

from terratheme.core.errors import TerrathemeError

#: Qt platforms that need no display server.
HEADLESS_PLATFORMS = frozenset({"offscreen", "minimal", "minimalegl", "vnc", "linuxfb",
                                "eglfs", "vkkhrdisplay"})
#: Debian packages of the libraries Qt's xcb platform plugin loads (from Qt 6.5).
XCB_PACKAGES = {
    "libxcb.so.1": "libxcb1", "libxcb-cursor.so.0": "libxcb-cursor0",
    "libxcb-icccm.so.4": "libxcb-icccm4", "libxcb-keysyms.so.1": "libxcb-keysyms1",
    "libxcb-image.so.0": "libxcb-image0", "libxcb-render-util.so.0": "libxcb-render-util0",
    "libxcb-randr.so.0": "libxcb-randr0", "libxcb-shape.so.0": "libxcb-shape0",
    "libxcb-xkb.so.1": "libxcb-xkb1", "libxcb-sync.so.1": "libxcb-sync1",
    "libxcb-xfixes.so.0": "libxcb-xfixes0", "libxkbcommon-x11.so.0": "libxkbcommon-x11-0",
    "libX11-xcb.so.1": "libx11-xcb1",
}
#: Seconds an X server has to accept the connection.
CONNECT_TIMEOUT_S = 3.0


def display_problem(env: Mapping[str, str] | None = None) -> str | None:
    """Why Qt could not open a window with ``env`` (default ``os.environ``), or None.

    One line naming the missing display variable, xcb library (with its Debian package),
    server or screen. Only Linux's X11 path is checked; headless platforms, Wayland and
    other systems are left to Qt.
    """
    env = os.environ if env is None else env
    platform = env.get("QT_QPA_PLATFORM", "").split(":")[0].strip().lower()
    if not sys.platform.startswith("linux") or platform in HEADLESS_PLATFORMS:
        return None
    if platform not in ("", "xcb") or (not platform and _wayland_answers(env)):
        return None
    display = env.get("DISPLAY", "")
    if not display:
        return ("no display: DISPLAY is not set (run it on a desktop or through ssh -X; "
                "a --screenshot works without one)")
    try:
        import ctypes
    except ImportError:  # a Python without ctypes: leave it to Qt
        return None
    # Every library the xcb plugin needs (the plugin itself pulls them all in), then the server.
    missing = _missing_library(ctypes)
    if missing is not None:
        package = XCB_PACKAGES.get(missing)
        hint = f"Debian/Ubuntu: apt-get install {package}; " if package else ""
        return (f"the editor needs the system library {missing} for an X display "
                f"({hint}setup.sh installs it as root)")
    return _server_problem(ctypes, display)


def _wayland_answers(env: Mapping[str, str]) -> bool:
    """A Wayland session's socket exists (a stale WAYLAND_DISPLAY leaves Qt to X11)."""
    name = env.get("WAYLAND_DISPLAY", "")
    if not name:
        return False
    path = Path(name) if name.startswith("/") else Path(env.get("XDG_RUNTIME_DIR", "")) / name
    return path.is_socket()


def _missing_library(ctypes) -> str | None:
    """The first library of the xcb plugin that cannot be loaded, or None."""
    for name in XCB_PACKAGES:
        try:
            ctypes.CDLL(name)
        except OSError:
            return name
    try:
        import PySide6
    except ImportError:
        return None
    plugin = Path(PySide6.__path__[0]) / "Qt" / "plugins" / "platforms" / "libqxcb.so"
    if not plugin.is_file():
        return None
    try:
        ctypes.CDLL(str(plugin))
    except OSError as exc:
        found = re.search(r"([\w.+-]+\.so[\w.]*): cannot open shared object", str(exc))
        return found.group(1) if found else str(plugin)
    return None


def _server_problem(ctypes, display: str) -> str | None:
    """Why the X server of ``display`` cannot be used (connection, screen), or None."""
    xcb = ctypes.CDLL("libxcb.so.1")
    xcb.xcb_connect.restype = ctypes.c_void_p
    xcb.xcb_connect.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
    xcb.xcb_connection_has_error.argtypes = [ctypes.c_void_p]
    xcb.xcb_disconnect.argtypes = [ctypes.c_void_p]
    xcb.xcb_get_setup.restype = ctypes.c_void_p
    xcb.xcb_get_setup.argtypes = [ctypes.c_void_p]
    xcb.xcb_setup_roots_length.argtypes = [ctypes.c_void_p]
    result: list = []

    def connect() -> None:
        screen = ctypes.c_int(0)
        connection = xcb.xcb_connect(display.encode(), ctypes.byref(screen))
        try:
            if xcb.xcb_connection_has_error(connection):
                result.append(f"cannot connect to the X display {display!r} "
                              "(is the X server running?)")
            elif not 0 <= screen.value < xcb.xcb_setup_roots_length(xcb.xcb_get_setup(
                    connection)):
                result.append(f"the X display {display!r} has no screen {screen.value}")
            else:
                result.append(None)
        finally:
            xcb.xcb_disconnect(connection)

    # A server that accepts and never answers would hold Qt (and this check) for good.
    worker = threading.Thread(target=connect, daemon=True, name="x-display-check")
    worker.start()
    worker.join(CONNECT_TIMEOUT_S)
    if not result:
        return f"the X display {display!r} does not answer within {CONNECT_TIMEOUT_S:g} s"
    return result[0]


def prepare_display(*, screenshot: bool) -> None:
    """Make sure Qt can start: for a screenshot, offscreen when there is no usable display;
    else TerrathemeError naming the problem."""
    problem = display_problem()
    if problem is None:
        return
    if screenshot:
        os.environ["QT_QPA_PLATFORM"] = "offscreen"
        # The offscreen platform's GL would still reach for a display that never answers.
        os.environ.pop("DISPLAY", None)
        os.environ.pop("WAYLAND_DISPLAY", None)
        return
    raise TerrathemeError(problem)
