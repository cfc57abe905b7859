"""terratheme applications: the `terratheme` CLI and the PySide6 editor, thin over core."""
