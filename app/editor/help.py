"""Help menu: keys and mouse, where the documentation is, about (version).

The key list is read from the window's own actions and tools, so it always
says what the window really does.
"""

from __future__ import annotations

import html
import platform
from pathlib import Path

from PySide6.QtCore import qVersion
from PySide6.QtGui import QKeySequence
from terratheme.app.editor.tools import TOOL_HELP, Tool

REPO = Path(__file__).resolve().parents[2]
#: the documents Help > Documentation points at, most useful first
DOCS = (REPO / "README.md", REPO / "docs")

MOUSE_HELP = (
    ("Left button", "use the active tool"),
    ("Wheel", "zoom about the cursor"),
    ("Middle or right button, or Space + left", "pan"),
)


def shortcut_rows(window) -> list[tuple[str, str]]:
    """``(keys, what)`` for every menu action of ``window`` that has a shortcut."""
    rows = []
    for menu_action in window.menuBar().actions():
        menu = menu_action.menu()
        if menu is None:
            continue
        for act in menu.actions():
            keys = ", ".join(k.toString(QKeySequence.SequenceFormat.NativeText)
                             for k in act.shortcuts())
            if keys:
                # An action whose text follows the document keeps its plain name in data().
                name = (act.data() or act.text()).replace("&", "").rstrip("…")
                rows.append((keys, f"{menu_action.text().replace('&', '')} > {name}"))
    return rows


def keys_help_html(window) -> str:
    """Help > Keys and mouse as HTML: tools, theme and brush keys, mouse, menu shortcuts."""
    sections = [
        ("Tools", [(t.shortcut, f"{t.label}: {TOOL_HELP[t]}") for t in Tool]
         + [("1 … 9", "select theme 1 … 9 of the palette"),
            ("[ and ]", "brush smaller / larger (diameter in grid vertices)")]),
        ("Mouse", list(MOUSE_HELP)),
        ("Menus", shortcut_rows(window)),
    ]
    body = ""
    for title, rows in sections:
        body += f"<tr><td colspan=2><h4>{title}</h4></td></tr>"
        body += "".join(f"<tr><td><b>{html.escape(k)}</b>&nbsp;&nbsp;</td>"
                        f"<td>{html.escape(v)}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def docs_text() -> str:
    """Where the documentation is (the repository's README and docs folder)."""
    found = [str(p) for p in DOCS if p.exists()]
    if not found:
        return ("The documentation is the README.md of the terratheme repository "
                "(not found beside this installation).")
    return "The documentation is in:\n" + "\n".join(found)


def about_text() -> str:
    """Help > About: program, version and what it runs on."""
    import PySide6
    import terratheme.core

    return (f"terratheme {terratheme.core.__version__}\n"
            "Thematic terrain textures: a coarse grid of theme indices plus small "
            "tileable theme textures, edited by hand with a live preview.\n\n"
            f"Python {platform.python_version()}, PySide6 {PySide6.__version__}, "
            f"Qt {qVersion()}")
