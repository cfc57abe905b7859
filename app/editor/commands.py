"""QUndoCommands wrapping the core model's undo atoms and theme changes."""

from __future__ import annotations

from typing import TYPE_CHECKING

from PySide6.QtGui import QUndoCommand

from core.edit.session import Atom
from core.themes.library import Theme

if TYPE_CHECKING:
    from app.editor.document import EditorDocument


class AtomCommand(QUndoCommand):
    """An edit already applied by the session (a stroke, fill, classification).

    The first ``redo`` (QUndoStack.push calls it) does nothing: the edit is
    already on the grid. Later ``undo``/``redo`` revert and re-apply the atom.
    """

    def __init__(self, doc: EditorDocument, atom: Atom, text: str) -> None:
        super().__init__(text)
        self.doc = doc
        self.atom = atom
        self._first = True

    def redo(self) -> None:
        if self._first:
            self._first = False
            return
        self._apply()

    def _apply(self) -> None:
        self.doc.session.apply(self.atom)

    def undo(self) -> None:
        self.doc.session.revert(self.atom)


class ThemeCommand(QUndoCommand):
    """Replace theme ``k`` (rename, recolour or a new texture)."""

    def __init__(self, doc: EditorDocument, k: int, new: Theme, text: str) -> None:
        super().__init__(text)
        self.doc = doc
        self.k = k
        self.old = doc.texture.library[k]
        self.new = new

    def redo(self) -> None:
        self.doc.set_theme(self.k, self.new)

    def undo(self) -> None:
        self.doc.set_theme(self.k, self.old)


class ScribbleCommand(AtomCommand):
    """A stroke in the scribble layer (already applied when pushed)."""

    def _apply(self) -> None:
        self.atom.apply(self.doc.texture.scribbles)
        self.doc.scribblesChanged.emit()

    def undo(self) -> None:
        self.atom.revert(self.doc.texture.scribbles)
        self.doc.scribblesChanged.emit()


class AddThemeCommand(QUndoCommand):
    """Append a theme to the library; undo removes it again."""

    def __init__(self, doc: EditorDocument, theme: Theme, text: str) -> None:
        super().__init__(text)
        self.doc = doc
        self.theme = theme

    def redo(self) -> None:
        self.doc.append_theme(self.theme)

    def undo(self) -> None:
        self.doc.remove_last_theme()
