"""Opening the editor window from the command line (and for the screenshot)."""

from __future__ import annotations

from pathlib import Path

from terratheme.app.editor.display import prepare_display
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.model.project import PROJECT_SUFFIX


def load_start_document(target: str | None, *, classify: bool):
    """The document to open: a project, a new project over a photo, the sample or an empty one.

    Returns ``(doc, wants_classification)``.
    """
    from terratheme.app.editor.document import EditorDocument
    from terratheme.app.editor.newproject import (
        empty_project,
        project_from_photo,
        sample_project_path,
    )

    if target is None:
        sample = sample_project_path()
        if sample is not None:
            return EditorDocument.open(sample), False
        return EditorDocument(empty_project()), False
    path = Path(target)
    if not path.exists():
        raise TerrathemeError(f"{path}: no such file")
    if path.suffix.lower() == PROJECT_SUFFIX:
        return EditorDocument.open(path), False
    doc = EditorDocument(project_from_photo(path))
    doc.fresh_from_photo = True
    return doc, classify


def run_editor(target: str | None, *, screenshot: str | None = None, classify: bool = True,
               size: tuple[int, int] = (1400, 860), timeout_s: float = 300.0) -> int:
    """Open the editor; with ``screenshot`` render the laid-out window to that PNG and exit."""
    import sys

    # A missing or unreachable display is one line, not Qt's abort (:mod:`.display`).
    prepare_display(screenshot=screenshot is not None)
    from PySide6.QtCore import (
        QBuffer,
        QByteArray,
        QElapsedTimer,
        QEventLoop,
        QIODevice,
        qInstallMessageHandler,
    )
    from PySide6.QtWidgets import QApplication
    from terratheme.app.editor.window import MainWindow
    from terratheme.core.edit.classification import ClassifyMode as Mode

    qInstallMessageHandler(_qt_message)
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("terratheme")
    error = None
    try:
        doc, wants_classification = load_start_document(target, classify=classify)
    except (TerrathemeError, OSError) as exc:
        if screenshot is not None:
            raise
        # Interactive: open an empty project and say what went wrong in a dialog.
        from terratheme.app.editor.document import EditorDocument
        from terratheme.app.editor.newproject import empty_project

        doc, wants_classification, error = EditorDocument(empty_project()), False, exc
    win = MainWindow(doc, interactive=screenshot is None)
    win.resize(*size)
    win.show()
    if wants_classification:
        win.start_classification(Mode.UNSUPERVISED_NEW)
    if screenshot is None:
        if error is not None:
            win.show_error(f"Cannot open {target}:\n{error}")
        return app.exec()
    # Lay out, wait for a running classification (bounded), then grab the window.
    timer = QElapsedTimer()
    timer.start()
    while win.job is not None and timer.elapsed() < timeout_s * 1000:
        app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 50)
    app.processEvents()
    try:
        if win.failure is not None:
            # A failed classification: no screenshot of a window that does not show it.
            raise TerrathemeError(win.failure)
        win.fit()
        app.processEvents()
        image = win.grab()
    finally:
        win.wait_for_jobs()
        win.doc.model.history.mark_saved()
        win.close()
    # Coded in memory, then written whole (a full disk keeps the old file, and libpng
    # says nothing on stderr).
    data = QByteArray()
    buffer = QBuffer(data)
    buffer.open(QIODevice.OpenModeFlag.WriteOnly)
    if not image.save(buffer, Path(screenshot).suffix.lstrip(".").lower() or None):
        raise TerrathemeError(f"cannot write the screenshot {screenshot}")
    buffer.close()
    write_bytes_atomic(screenshot, bytes(data))
    return 0


#: Qt messages that say nothing to a user (the offscreen platform's, on every screenshot).
QUIET_QT_MESSAGES = ("does not support propagateSizeHints",)


def _qt_message(mode, context, message: str) -> None:
    """Qt's messages on stderr as Qt prints them, but for :data:`QUIET_QT_MESSAGES`."""
    import sys

    if not any(quiet in message for quiet in QUIET_QT_MESSAGES):
        print(message, file=sys.stderr)
