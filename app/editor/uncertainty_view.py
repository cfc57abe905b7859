"""View > Show uncertainty: a translucent tint where the last classification was least sure.

The toggle, the window's ``show_uncertainty`` flag, the index canvas's tint
and the status-bar share follow one setter (:meth:`UncertaintyMixin.
set_show_uncertainty`); the document's ``confidenceChanged`` rebuilds or
removes the tint, so it disappears when there is no confidence map. Which
pixels are uncertain is decided in :mod:`core.edit.uncertainty`.
"""

from __future__ import annotations

from PySide6.QtCore import QRectF
from PySide6.QtGui import QAction, QKeySequence, QPainter
from PySide6.QtWidgets import QLabel
from terratheme.app.editor.imaging import ZoomPyramid
from terratheme.core.edit import UNCERTAIN_SHARE, uncertainty_rgba


class UncertaintyMixin:
    """For :class:`~app.editor.window.MainWindow`: the uncertainty toggle and overlay."""

    show_uncertainty = False
    uncertainty_pyramid: ZoomPyramid | None = None

    def build_uncertainty_action(self, menu) -> QAction:
        act = QAction("Show &uncertainty (least confident 10% of the photo)", self)
        act.setShortcut(QKeySequence("U"))
        act.setCheckable(True)
        act.setStatusTip("Tint where the last classification was least sure: "
                         "add correction strokes there")
        act.toggled.connect(self.set_show_uncertainty)
        menu.addAction(act)
        self.uncertainty_action = act
        self.uncertainty_label = QLabel()
        self.uncertainty_label.setVisible(False)
        self.statusBar().addPermanentWidget(self.uncertainty_label)
        return act

    def set_show_uncertainty(self, on: bool, quiet: bool = False) -> None:
        """Show or hide the tint; the toggle follows (off when there is no confidence map)."""
        doc = self.doc
        mask = None if doc is None else doc.model.uncertain()
        if on and mask is None and not quiet:
            self.statusBar().showMessage(
                "no confidence map: classify the photo first (Classify menu)", 4000)
        on = bool(on) and mask is not None
        self.show_uncertainty = on
        if self.uncertainty_action.isChecked() != self.show_uncertainty:
            self.uncertainty_action.blockSignals(True)
            self.uncertainty_action.setChecked(self.show_uncertainty)
            self.uncertainty_action.blockSignals(False)
        if self.show_uncertainty:
            self.uncertainty_pyramid = ZoomPyramid(uncertainty_rgba(mask),
                                               extent=doc.photo_extent())
            self.uncertainty_label.setText(
                f"uncertain: {100 * mask.mean():.1f}% of the photo "
                f"(lowest {100 * UNCERTAIN_SHARE:.0f}% confidence, as regions)")
        else:
            self.uncertainty_pyramid = None
        self.uncertainty_label.setVisible(self.show_uncertainty)
        self.index_canvas.update()

    def _confidence_changed(self) -> None:
        """A new or cleared confidence map: rebuild or drop the tint, keeping the toggle."""
        self.set_show_uncertainty(self.show_uncertainty, quiet=True)

    def _paint_uncertainty(self, p: QPainter, visible: QRectF, scale: float) -> None:
        if self.show_uncertainty and self.uncertainty_pyramid is not None:
            self.uncertainty_pyramid.draw(p, visible, scale, 1.0, smooth=False)
