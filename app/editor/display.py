"""Whether Qt can open a window here, checked before Qt is started.

Qt ends the process with an abort (exit 134 and a page of plugin hints) when
its platform plugin cannot start: no ``DISPLAY``, an X server that does not
answer, or a system library the xcb plugin needs missing. The editor checks
those first, so a user gets one line naming the problem (exit 2). A
screenshot needs no display: without one it is drawn offscreen.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from collections.abc import Mapping

from core.errors import TerrathemeError

#: Qt platforms that need no display server.
HEADLESS_PLATFORMS = frozenset({"offscreen", "minimal", "minimalegl", "vnc", "linuxfb",
                                "eglfs", "vkkhrdisplay"})
#: Libraries Qt's xcb platform plugin loads (from Qt 6.5), and their Debian packages.
XCB_LIBRARIES = (
    ("libxcb-cursor.so.0", "libxcb-cursor0"),
    ("libxcb-icccm.so.4", "libxcb-icccm4"),
    ("libxcb-keysyms.so.1", "libxcb-keysyms1"),
    ("libxcb-image.so.0", "libxcb-image0"),
    ("libxcb-render-util.so.0", "libxcb-render-util0"),
    ("libxcb-randr.so.0", "libxcb-randr0"),
    ("libxcb-shape.so.0", "libxcb-shape0"),
    ("libxcb-xkb.so.1", "libxcb-xkb1"),
    ("libxkbcommon-x11.so.0", "libxkbcommon-x11-0"),
    ("libX11-xcb.so.1", "libx11-xcb1"),
)


def display_problem(env: Mapping[str, str] | None = None) -> str | None:
    """Why Qt could not open a window with this environment, or None when it can.

    Only Linux's X11 path (Qt's default there) is checked: an explicit headless
    platform (``QT_QPA_PLATFORM=offscreen`` ...), a Wayland session and other
    systems are left to Qt.
    """
    env = os.environ if env is None else env
    platform = env.get("QT_QPA_PLATFORM", "").split(":")[0].strip().lower()
    if not sys.platform.startswith("linux") or platform in HEADLESS_PLATFORMS:
        return None
    if platform not in ("", "xcb") or (not platform and env.get("WAYLAND_DISPLAY")):
        return None
    display = env.get("DISPLAY", "")
    if not display:
        return ("no display: DISPLAY is not set (run it on a desktop or through ssh -X; "
                "a --screenshot works without one)")
    # Each library the xcb plugin needs, then a connection to the server.
    for name, package in XCB_LIBRARIES:
        try:
            ctypes.CDLL(name)
        except OSError:
            return (f"the editor needs the system library {name} for an X display "
                    f"(Debian/Ubuntu: apt-get install {package}; setup.sh installs it as root)")
    path = ctypes.util.find_library("xcb")
    if path is None:
        return "the editor needs the system library libxcb.so.1 for an X display"
    xcb = ctypes.CDLL(path)
    xcb.xcb_connect.restype = ctypes.c_void_p
    xcb.xcb_connect.argtypes = [ctypes.c_char_p, ctypes.c_void_p]
    xcb.xcb_connection_has_error.argtypes = [ctypes.c_void_p]
    xcb.xcb_disconnect.argtypes = [ctypes.c_void_p]
    connection = xcb.xcb_connect(display.encode(), None)
    try:
        failed = xcb.xcb_connection_has_error(connection)
    finally:
        xcb.xcb_disconnect(connection)
    if failed:
        return f"cannot connect to the X display {display!r} (is the X server running?)"
    return None


def prepare_display(*, screenshot: bool) -> None:
    """Make sure Qt can start: for a screenshot, offscreen when there is no usable display.

    Raises
    ------
    TerrathemeError
        No usable display for the editor's window (:func:`display_problem`).
    """
    problem = display_problem()
    if problem is None:
        return
    if screenshot:
        os.environ["QT_QPA_PLATFORM"] = "offscreen"
        return
    raise TerrathemeError(problem)
