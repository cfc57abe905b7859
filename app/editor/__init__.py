"""The PySide6 editor: a thin view over the core edit document (``core.edit.EditDocument``).

``app.editor.launch.run_editor(target, screenshot=None)`` opens the window;
``app/commands/app.py`` is the command line. Importing the package applies
:mod:`app.editor.qt_compat`'s guard against a PySide6 6.12 reference-count
bug that otherwise aborts the interpreter after a few thousand Qt calls.
"""

from terratheme.app.editor.qt_compat import guard_none_refcount

guard_none_refcount()
