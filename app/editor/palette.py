"""The theme palette: thumbnails and names; add, rename, recolour, assign a texture file."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QSize, Qt, Signal
from PySide6.QtGui import QColor, QIcon, QImage, QPainter, QPixmap
from PySide6.QtWidgets import (
    QColorDialog,
    QFileDialog,
    QHBoxLayout,
    QInputDialog,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QVBoxLayout,
    QWidget,
)
from terratheme.app.editor.document import EditorDocument
from terratheme.app.editor.imaging import qimage_view
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.colour_map import NEUTRAL
from terratheme.core.themes.library import Theme

THUMB = 44


def theme_icon(theme: Theme, gain: np.ndarray | None = None) -> QIcon:
    """A thumbnail of the theme's texture with its display colour as a side bar.

    ``gain``: (3,) the colour map's mean stored gain over the theme (NaN or None: no map
    there); the thumbnail shows the texture under it, as the render does, so a detail
    theme (mid-grey, its colour in the map) shows its colour.
    """
    tex = np.asarray(theme.texture)
    if gain is not None and np.isfinite(gain).all():
        tex = np.clip(tex * (np.asarray(gain, np.float32) / NEUTRAL), 0, 255).astype(np.uint8)
    tex = np.ascontiguousarray(tex)
    img = qimage_view(tex).scaled(THUMB, THUMB, Qt.AspectRatioMode.IgnoreAspectRatio,
                                  Qt.TransformationMode.SmoothTransformation)
    pix = QPixmap(THUMB + 10, THUMB)
    pix.fill(QColor(0, 0, 0, 0))
    p = QPainter(pix)
    p.fillRect(0, 0, 8, THUMB, QColor(*theme.colour))
    p.drawImage(10, 0, img.convertToFormat(QImage.Format.Format_RGB32))
    p.end()
    return QIcon(pix)


class ThemePalette(QWidget):
    """Lists the themes; ``currentChanged(k)`` when the user picks one."""

    currentChanged = Signal(int)
    error = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.doc: EditorDocument | None = None
        self.list = QListWidget()
        self.list.setIconSize(QSize(THUMB + 10, THUMB))
        self.list.setSpacing(1)
        self.list.currentRowChanged.connect(self._row_changed)
        self.list.itemDoubleClicked.connect(lambda _item: self.rename())
        buttons = QHBoxLayout()
        for text, slot, tip in (
            ("Add", self.add, "Add a theme from a texture file"),
            ("Rename", self.rename, "Rename the selected theme"),
            ("Colour", self.recolour, "Change the display colour"),
            ("Texture", self.assign_texture, "Assign a texture file"),
        ):
            b = QPushButton(text)
            b.setToolTip(tip)
            b.clicked.connect(slot)
            buttons.addWidget(b)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addWidget(self.list)
        layout.addLayout(buttons)

    def set_document(self, doc: EditorDocument) -> None:
        self.doc = doc
        doc.libraryChanged.connect(self.refresh)
        self.refresh()
        self.list.setCurrentRow(0)

    @property
    def current(self) -> int:
        return max(self.list.currentRow(), 0)

    def select(self, k: int) -> None:
        if 0 <= k < self.list.count():
            self.list.setCurrentRow(k)

    def refresh(self) -> None:
        if self.doc is None:
            return
        row = self.list.currentRow()
        self.list.blockSignals(True)
        self.list.clear()
        gains = self.doc.model.data.colour_gains()
        for k, theme in enumerate(self.doc.texture.library):
            label = f"{k + 1}  {theme.name}" if k < 9 else f"    {theme.name}"
            item = QListWidgetItem(theme_icon(theme, None if gains is None else gains[k]), label)
            item.setToolTip(f"{theme.name}: colour {theme.colour}, "
                            f"texture {theme.texture.shape[1]} x {theme.texture.shape[0]}"
                            f"{', ' + theme.source if theme.source else ''}")
            self.list.addItem(item)
        self.list.blockSignals(False)
        self.list.setCurrentRow(min(max(row, 0), self.list.count() - 1))

    def _row_changed(self, row: int) -> None:
        if row >= 0:
            self.currentChanged.emit(row)

    # -- actions -------------------------------------------------------------
    def _texture_file(self) -> tuple[np.ndarray, str] | None:
        from terratheme.core.io.images import Bands, read_image

        path, _ = QFileDialog.getOpenFileName(self, "Theme texture", "",
                                              "Images (*.png *.jpg *.jpeg *.tif *.tiff *.exr)")
        if not path:
            return None
        try:
            return read_image(path, dtype=np.uint8, bands=Bands.PHOTO), path
        except TerrathemeError as exc:
            self.error.emit(str(exc))
            return None

    def add(self) -> None:
        if self.doc is None:
            return
        got = self._texture_file()
        if got is None:
            return
        tex, path = got
        name, ok = QInputDialog.getText(self, "New theme", "Name:")
        if not ok or not name.strip():
            return
        mean = tuple(int(v) for v in tex[..., :3].reshape(-1, 3).mean(axis=0))
        try:
            k = self.doc.model.add_theme(Theme(name.strip(), mean, tex, source=path))
        except TerrathemeError as exc:
            self.error.emit(str(exc))
            return
        self.select(k)

    def rename(self) -> None:
        if self.doc is None:
            return
        k = self.current
        theme = self.doc.texture.library[k]
        name, ok = QInputDialog.getText(self, "Rename theme", "Name:", text=theme.name)
        if ok and name.strip() and name.strip() != theme.name:
            self._change(k, theme, f"rename theme to {name.strip()}", name=name.strip())

    def recolour(self) -> None:
        if self.doc is None:
            return
        k = self.current
        theme = self.doc.texture.library[k]
        c = QColorDialog.getColor(QColor(*theme.colour), self, f"Colour of {theme.name}")
        if c.isValid():
            self._change(k, theme, f"recolour {theme.name}", colour=(c.red(), c.green(), c.blue()))

    def assign_texture(self) -> None:
        if self.doc is None:
            return
        got = self._texture_file()
        if got is not None:
            k = self.current
            theme = self.doc.texture.library[k]
            self._change(k, theme, f"new texture for {theme.name}", texture=got[0],
                         source=got[1])

    def _change(self, k: int, theme: Theme, text: str, **changes: object) -> None:
        try:
            self.doc.model.replace_theme(k, theme.with_(**changes), text)
        except TerrathemeError as exc:
            self.error.emit(str(exc))
