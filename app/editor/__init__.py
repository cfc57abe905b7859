"""The PySide6 editor: a thin view over the core edit document (``core.edit.EditDocument``).

``launch.run_editor`` opens the window. Importing the package applies
:mod:`.qt_compat`'s guard against a PySide6 6.12 reference-count bug.
"""

from terratheme.app.editor.qt_compat import guard_none_refcount

guard_none_refcount()
