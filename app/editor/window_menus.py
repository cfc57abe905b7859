"""Menus of the main window: File, Edit, View, Classify; file and classification actions.

Help is in :mod:`app.editor.help`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QFileDialog, QMessageBox, QProgressBar, QPushButton
from terratheme.app.editor.classify_job import ClassifyJob, ClassifyResult, Mode, keep_alive
from terratheme.app.editor.document import EditorDocument
from terratheme.app.editor.newproject import empty_project
from terratheme.core.edit import ClassificationUpdate
from terratheme.core.errors import TerrathemeError

PROJECT_FILTER = "terratheme project (*.ttproj)"


class MenuMixin:
    """File/Edit/View/Classify menus for :class:`~app.editor.window.MainWindow`."""

    def build_menus(self) -> None:
        mb = self.menuBar()
        file = mb.addMenu("&File")
        self._act(file, "&New", self.new_project, QKeySequence.StandardKey.New)
        self._act(file, "&Open…", self.open_dialog, QKeySequence.StandardKey.Open)
        self._act(file, "&Save", self.save, QKeySequence.StandardKey.Save)
        self._act(file, "Save &As…", self.save_as, "Ctrl+Shift+S")
        file.addSeparator()
        self._act(file, "Export &render (PNG/TIFF/EXR)…", self.export_render, "Ctrl+E")
        self._act(file, "Export &packed index layer…", self.export_packed)
        file.addSeparator()
        self._act(file, "&Quit", self.close, QKeySequence.StandardKey.Quit)
        self.edit_menu = mb.addMenu("&Edit")
        # Bound once; the text and enabled state follow the core history.
        self.undo_action = self._act(self.edit_menu, "&Undo", lambda: self.doc.model.undo(),
                                     "Ctrl+Z")
        self.redo_action = self._act(self.edit_menu, "&Redo", lambda: self.doc.model.redo())
        self.redo_action.setShortcuts([QKeySequence("Ctrl+Shift+Z"), QKeySequence("Ctrl+Y")])
        self.undo_action.setData("Undo")
        self.redo_action.setData("Redo")
        view = mb.addMenu("&View")
        self._act(view, "&Fit to window", self.fit, "Ctrl+0")
        self._act(view, "Side by side", lambda: self.set_layout("both"), "Ctrl+1")
        self._act(view, "Index map only", lambda: self.set_layout("index"), "Ctrl+2")
        self._act(view, "Render only", lambda: self.set_layout("render"), "Ctrl+3")
        self._act(view, "&Toggle index map / render", self.toggle_layout, "T")
        view.addSeparator()
        self.grid_action = self._act(view, "Cell &grid", self._toggle("show_grid"), "G", True)
        self.photo_action = self._act(view, "&Photo under the index map",
                                      self._toggle("show_photo"), "P", True)
        self.fidelity_action = self._act(view, "Fidelity &heat map (render vs photo)",
                                         self._toggle("show_fidelity"), "H", False)
        self.build_uncertainty_action(view)
        cls = mb.addMenu("&Classify")
        for mode in Mode:
            self._act(cls, mode.value + "…", lambda _=False, m=mode: self.start_classification(m))
        cls.addSeparator()
        # Off by default: such a model fits this photo only (see classify --position).
        self.position_action = self._act(cls, "Scribbles: use where the strokes &lie",
                                         lambda _=False: None, checked=False)
        self.cancel_action = self._act(cls, "&Cancel classification", self.cancel_classification,
                                       "Esc")
        self.cancel_action.setEnabled(False)
        self.progress = QProgressBar()
        self.progress.setMaximumWidth(220)
        self.progress.setVisible(False)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setVisible(False)
        self.cancel_button.clicked.connect(self.cancel_classification)
        self.statusBar().addPermanentWidget(self.progress)
        self.statusBar().addPermanentWidget(self.cancel_button)
        self.build_help_menu(mb)

    def _act(self, menu, text, slot, shortcut=None, checked=None) -> QAction:
        act = QAction(text, self)
        if shortcut is not None:
            act.setShortcut(QKeySequence(shortcut))
        if checked is not None:
            act.setCheckable(True)
            act.setChecked(checked)
        act.triggered.connect(slot)
        menu.addAction(act)
        return act

    def _toggle(self, attr: str):
        def flip(checked: bool) -> None:
            setattr(self, attr, bool(checked))
            if attr == "show_fidelity":
                if checked and self.doc.texture.photo is None:
                    self.statusBar().showMessage("the fidelity view needs a photo", 4000)
                summary = self.doc.fidelity_summary() if checked else None
                self.index_canvas.title = (
                    "Fidelity: per-cell colour difference render vs photo "
                    "(CIEDE2000, dark 0 -> bright 25+)"
                    + (f"; whole texture: {summary}" if summary else "")
                    if checked else "Index map")
            self._repaint()

        return flip

    # -- layout ----------------------------------------------------------------
    def set_layout(self, which: str) -> None:
        self.index_canvas.setVisible(which in ("both", "index"))
        self.render_canvas.setVisible(which in ("both", "render"))

    def toggle_layout(self) -> None:
        self.set_layout("render" if self.index_canvas.isVisible() else "index")

    # -- files ---------------------------------------------------------------
    def _confirm_discard(self) -> bool:
        if self.doc is None or self.doc.clean:
            return True
        answer = QMessageBox.question(
            self, "terratheme", "Discard the unsaved changes?",
            QMessageBox.StandardButton.Discard | QMessageBox.StandardButton.Cancel)
        return answer == QMessageBox.StandardButton.Discard

    def new_project(self) -> None:
        if self._confirm_discard():
            self.set_document(EditorDocument(empty_project()))

    def open_dialog(self) -> None:
        if not self._confirm_discard():
            return
        path, _ = QFileDialog.getOpenFileName(self, "Open project", "", PROJECT_FILTER)
        if path:
            self.open_path(path)

    def open_path(self, path: str | Path) -> bool:
        """Open a project; a damaged or unreadable file shows an error dialog."""
        try:
            doc = EditorDocument.open(path, progress=self.render_progress())
        except (TerrathemeError, OSError) as exc:
            self.show_error(f"Cannot open {path}:\n{exc}")
            return False
        self.set_document(doc)
        return True

    def render_progress(self):
        """A progress callback for a long first render: the status-bar bar, kept painted."""
        from PySide6.QtCore import QEventLoop
        from PySide6.QtWidgets import QApplication

        def progress(done: int, total: int) -> None:
            self.progress.setVisible(done < total)
            self.progress.setRange(0, max(total, 1))
            self.progress.setValue(done)
            self.statusBar().showMessage("rendering…" if done < total else "", 2000)
            # Repaint only: no user input while the document is half made.
            QApplication.processEvents(QEventLoop.ProcessEventsFlag.ExcludeUserInputEvents)

        return progress

    def save(self) -> bool:
        if self.doc.path is None:
            return self.save_as()
        return self._save_to(self.doc.path)

    def save_as(self) -> bool:
        path, _ = QFileDialog.getSaveFileName(self, "Save project", "untitled.ttproj",
                                              PROJECT_FILTER)
        if not path:
            return False
        if not path.endswith(".ttproj"):
            path += ".ttproj"
        return self._save_to(path)

    def _save_to(self, path) -> bool:
        try:
            saved = self.doc.save(path)
        except (TerrathemeError, OSError) as exc:
            self.show_error(f"Cannot save {path}:\n{exc}")
            return False
        self.statusBar().showMessage(f"saved {saved}", 4000)
        self._update_title()
        return True

    def export_render(self, path: str | None = None) -> bool:
        """The preview render as an image (PNG, TIFF or EXR)."""
        from terratheme.core.io.images import write_image

        return self._export(path, "Export render", "render.png",
                            "Images (*.png *.tif *.tiff *.exr)",
                            lambda out: write_image(out, self.doc.preview.image))

    def export_packed(self, path: str | None = None) -> bool:
        """The vertex index grid packed along a Hilbert curve (``core.packing``)."""

        def write(out: str) -> None:
            try:
                from terratheme.core.packing import pack
            except ImportError as exc:
                raise TerrathemeError("the packer (core.packing.pack) is not available "
                                      "in this build") from exc
            pack(self.doc.texture.grid.indices).save(out)

        return self._export(path, "Export packed index layer", "index.sfc",
                            "Packed layer (*.sfc)", write)

    def _export(self, path: str | None, title: str, default_name: str, file_filter: str,
                write: Callable[[str], None]) -> bool:
        """``write(path)``, asking for the path unless given; errors go to a dialog."""
        if not path:
            path, _ = QFileDialog.getSaveFileName(self, title, default_name, file_filter)
        if not path:
            return False
        try:
            write(path)
        except (TerrathemeError, OSError) as exc:
            self.show_error(f"Cannot export {path}:\n{exc}")
            return False
        self.statusBar().showMessage(f"exported {path}", 4000)
        return True

    # -- classification --------------------------------------------------------
    def start_classification(self, mode: Mode) -> ClassifyJob | None:
        """Classify the project's photo on a worker thread (progress bar, Cancel)."""
        tex = self.doc.texture
        if tex.photo is None:
            self.show_error("Classification needs a photo: start a project with "
                            "`terratheme app PHOTO`.")
            return None
        if self.job is not None:
            return None
        scribbles = None if tex.scribbles is None else tex.scribbles.copy()
        # Scribble runs reuse the class prior of the first strokes (same classes painted).
        prior = self.doc.model.prior_for_scribbles() if mode is Mode.SCRIBBLES else None
        job = ClassifyJob(mode, tex.photo, scribbles, tex.library, tex.grid.cell,
                          tex.grid.indices.shape, class_weights=prior,
                          position=mode is Mode.SCRIBBLES and self.position_action.isChecked())
        keep_alive(job)
        job.progressed.connect(self._job_progress)
        job.succeeded.connect(lambda result, j=job: self._job_done(j, result))
        job.failed.connect(lambda msg: self.show_error(f"Classification failed:\n{msg}"))
        job.finished.connect(lambda j=job: self._job_finished(j))
        self.job = job
        self.all_jobs.append(job)
        self.progress.setRange(0, 0)
        self.progress.setVisible(True)
        self.cancel_button.setVisible(True)
        self.cancel_action.setEnabled(True)
        kept = " (keeping the first strokes' class prior)" if prior else ""
        self.statusBar().showMessage(f"classifying: {mode.value}{kept}")
        job.start()
        return job

    def cancel_classification(self) -> None:
        if self.job is not None:
            self.job.cancel()
            self.statusBar().showMessage("classification cancelled", 4000)
            self._job_finished(self.job)

    def _job_progress(self, done: int, total: int) -> None:
        self.progress.setRange(0, max(total, 1))
        self.progress.setValue(done)

    def _job_done(self, job: ClassifyJob, result: ClassifyResult) -> None:
        """Apply a classification result as one undo step of the core document."""
        if job is not self.job or job.cancelled:
            return
        doc = self.doc
        model = doc.model
        # A project just started over a photo: its themes are the classes, nothing else.
        fresh = doc.fresh_from_photo and bool(result.new_themes) and not model.history.can_undo
        # The job numbers new themes after the current library.
        indices = (result.indices.astype(np.int64) - len(doc.texture.library) if fresh
                   else result.indices)
        unchanged = not result.new_themes and np.array_equal(indices, doc.texture.grid.indices)
        scribble_run = job.args[0] is Mode.SCRIBBLES
        try:
            model.apply_classification(ClassificationUpdate(
                indices, new_themes=result.new_themes, replace_themes=fresh,
                confidence=result.confidence,
                scribble_classes=result.scribble_classes if scribble_run else None,
                class_weights=result.class_weights))
        except TerrathemeError as exc:
            self.show_error(f"Classification result not applied:\n{exc}")
            return
        doc.fresh_from_photo = doc.fresh_from_photo and not fresh
        if unchanged:
            # A rerun: say so (only the confidence map and prior were replaced).
            self.statusBar().showMessage("classified: the grid is unchanged", 6000)
        else:
            self.statusBar().showMessage(f"classified into {result.n_classes} classes", 6000)

    def _job_finished(self, job: ClassifyJob) -> None:
        if job is not self.job:
            return
        self.job = None
        self.progress.setVisible(False)
        self.cancel_button.setVisible(False)
        self.cancel_action.setEnabled(False)

    def wait_for_jobs(self, msecs: int = 30000) -> None:
        """Cancel and join every classification thread (before the window closes)."""
        for job in self.all_jobs:
            job.cancel()
            job.wait(msecs)
        self.all_jobs = [j for j in self.all_jobs if j.isRunning()]
        if getattr(self, "perspective_tab", None) is not None:
            self.perspective_tab.wait(msecs)

    def closeEvent(self, event) -> None:
        if not self._confirm_discard():
            event.ignore()
            return
        self.wait_for_jobs()
        event.accept()

    # -- perspective -----------------------------------------------------------
    def update_perspective_tab(self) -> None:
        """Add or refresh the perspective preview tab (when core.perspective is available)."""
        try:
            from terratheme.app.editor.perspective_tab import PerspectiveTab
        except ImportError:
            return
        if getattr(self, "perspective_tab", None) is None:
            self.perspective_tab = PerspectiveTab()
            self.tabs.addTab(self.perspective_tab, "Perspective")
        self.perspective_tab.set_document(self.doc)
