"""Classification on a worker thread, with progress and Cancel.

:func:`core.edit.classification.run_classification` runs off the GUI thread; the window
applies the result as one undoable step. Cancel is cooperative: the progress callback
raises at the classifier's next tile, and a result after Cancel is dropped.
"""

from __future__ import annotations

from PySide6.QtCore import QObject, QThread, Signal
from terratheme.core.edit.classification import ClassifyMode, run_classification
from terratheme.core.themes.library import ThemeLibrary

_LIVE: set[QThread] = set()


def keep_alive(thread: QThread) -> QThread:
    """Hold a parentless worker thread until it finishes (Qt aborts on a running thread
    destroyed with its window)."""
    _LIVE.add(thread)
    thread.finished.connect(lambda: _LIVE.discard(thread))
    return thread


class Cancelled(Exception):
    """Raised inside the classifier's progress callback after Cancel."""


class ClassifyJob(QThread):
    """Runs :func:`run_classification` on its own thread.

    Signals: ``progressed(done, total)``, ``succeeded((ClassificationUpdate, n_classes))``,
    ``failed(str)``; after :meth:`cancel` none but ``finished`` is emitted.
    """

    progressed = Signal(int, int)
    succeeded = Signal(object)
    failed = Signal(str)

    def __init__(self, mode: ClassifyMode, photo, scribbles, library, cell, grid_shape,
                 parent: QObject | None = None, class_weights=None,
                 position: bool = False, replace_themes: bool = False) -> None:
        super().__init__(parent)
        self.args = (mode, photo, scribbles, ThemeLibrary(library), cell, grid_shape)
        self.class_weights = class_weights
        self.position = position
        self.replace_themes = replace_themes
        self.cancelled = False

    def cancel(self) -> None:
        self.cancelled = True

    def _progress(self, done: int, total: int) -> None:
        if self.cancelled:
            raise Cancelled
        self.progressed.emit(int(done), int(total))

    def run(self) -> None:
        try:
            result = run_classification(*self.args, progress=self._progress,
                                        class_weights=self.class_weights,
                                        position=self.position,
                                        replace_themes=self.replace_themes)
        except Cancelled:
            return
        except Exception as exc:  # reported in the window, never a crash
            if not self.cancelled:
                self.failed.emit(str(exc) or type(exc).__name__)
            return
        if not self.cancelled:
            self.succeeded.emit(result)
