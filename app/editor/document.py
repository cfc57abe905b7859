"""The open project as the window sees it: the core document, Qt signals and images.

``EditorDocument`` wraps one :class:`core.edit.EditDocument` (``.model``), which holds
everything edited and the one undo history. It only forwards: the model's events become
Qt signals, and the images the canvases draw are refreshed where an event says. Undo /
Redo call the model's (no QUndoStack: two histories could disagree, and one keeps every
undo rule testable without Qt).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, QRectF, Signal
from terratheme.app.editor.imaging import ZoomPyramid
from terratheme.core.edit import (
    ColourMapChange,
    EditDocument,
    GridChange,
    HistoryChange,
    RenderPreview,
    ThemeChange,
    fidelity_map,
    heat_colours,
)
from terratheme.core.errors import TerrathemeError
from terratheme.core.fidelity import fidelity, texture_cost
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.project import load_checked_project

EVERYWHERE = QRectF(-1e9, -1e9, 2e9, 2e9)


class EditorDocument(QObject):
    """A project open in the editor.

    Parameters
    ----------
    source : ThematicTexture or core EditDocument

    Signals
    -------
    regionChanged(QRectF)
        Texels whose index colours or render changed.
    libraryChanged()
        A theme was added, removed, renamed, recoloured or retextured.
    scribblesChanged(ScribbleChange)
        The scribble layer changed (a block of it, or the whole layer).
    confidenceChanged()
        A classification's confidence map was set or cleared.
    historyChanged(HistoryChange)
        The undo history moved (labels of Undo / Redo, saved or not).
    """

    regionChanged = Signal(QRectF)
    libraryChanged = Signal()
    scribblesChanged = Signal(object)
    confidenceChanged = Signal()
    historyChanged = Signal(object)

    def __init__(self, source: ThematicTexture | EditDocument, path: str | Path | None = None,
                 progress=None) -> None:
        super().__init__()
        self.model = source if isinstance(source, EditDocument) else EditDocument(source)
        self.path = Path(path) if path else None
        #: a project just started over a photo (classification replaces its themes)
        self.fresh_from_photo = False
        texture = self.model.texture
        self.preview = RenderPreview(texture, progress=progress)
        self.render_pyramid = ZoomPyramid(self.preview.image)
        n, m = texture.grid.cell
        gh1, gw1 = texture.grid.indices.shape
        self.index_rgb = np.ascontiguousarray(texture.library.colours[texture.grid.indices])
        # Vertex (i, j) sits at texel (i*N, j*M): its pixel spans half a cell either side.
        self.index_pyramid = ZoomPyramid(self.index_rgb, extent=(gw1 * n, gh1 * m),
                                         origin=(-n / 2, -m / 2))
        self.photo_pyramid: ZoomPyramid | None = None
        self._make_photo_pyramid()
        self._fidelity: np.ndarray | None = None
        self._summary: str | None = None
        self.fidelity_pyramid: ZoomPyramid | None = None
        events = self.model.events
        events.grid.connect(self._on_grid)
        events.colour_map.connect(self._on_colour_map)
        events.themes.connect(self._on_themes)
        events.scribbles.connect(self.scribblesChanged.emit)
        events.confidence.connect(lambda _e: self.confidenceChanged.emit())
        events.history.connect(self.historyChanged.emit)

    # -- geometry and state ----------------------------------------------------
    @property
    def texture(self) -> ThematicTexture:
        return self.model.texture

    @property
    def extent(self) -> tuple[int, int]:
        """``(width, height)`` of the render in texels."""
        return self.texture.grid.texture_size

    def photo_extent(self) -> tuple[float, float] | None:
        return self.model.photo_extent()

    def to_vertex(self, x: float, y: float) -> tuple[float, float]:
        return self.model.texel_to_vertex(x, y)

    @property
    def clean(self) -> bool:
        """Whether the document is as it was last saved or opened."""
        return self.model.history.clean

    def history_state(self) -> HistoryChange:
        h = self.model.history
        return HistoryChange(h.undo_label, h.redo_label, h.clean)

    # -- model events -> images and signals -------------------------------------------
    def _on_grid(self, change: GridChange) -> None:
        ind = self.texture.grid.indices
        self.index_rgb[change.rows, change.cols] = self.texture.library.colours[
            ind[change.rows, change.cols]]
        self.index_pyramid.update_region(change.cols.start, change.rows.start,
                                         change.cols.stop - change.cols.start,
                                         change.rows.stop - change.rows.start)
        region = self.preview.refresh(change)
        if region is not None:
            self.render_pyramid.update_region(*region)
        self._fidelity = None
        self._summary = None
        n, m = self.texture.grid.cell
        vr = QRectF((change.cols.start - 1) * n, (change.rows.start - 1) * m,
                    (change.cols.stop - change.cols.start + 2) * n,
                    (change.rows.stop - change.rows.start + 2) * m)
        self.regionChanged.emit(vr if region is None else vr.united(QRectF(*region)))

    def _on_colour_map(self, change: ColourMapChange) -> None:
        self.preview.refresh_region(change.region)
        region = change.region or (0, 0, *self.extent)
        self.render_pyramid.update_region(*region)
        self._fidelity = None
        self._summary = None
        self.regionChanged.emit(QRectF(*region))

    def _on_themes(self, change: ThemeChange) -> None:
        if change.colours:
            self.index_rgb[...] = self.texture.library.colours[self.texture.grid.indices]
            self.index_pyramid.update_region(0, 0, *self.index_rgb.shape[1::-1])
        if change.textures:
            self.preview.refresh_all()
            self.render_pyramid.update_region(0, 0, *self.extent)
            self._fidelity = None
        self._summary = None
        self.libraryChanged.emit()
        self.regionChanged.emit(EVERYWHERE)

    def _make_photo_pyramid(self) -> None:
        photo = self.model.photo
        self.photo_pyramid = (None if photo is None else
                              ZoomPyramid(photo, extent=self.photo_extent()))

    # -- views of the layers -------------------------------------------------------
    def scribble_rgba(self, rows: slice = slice(None), cols: slice = slice(None)
                      ) -> np.ndarray | None:
        """The scribble layer (or a block of it) as (h, w, 4) uint8: theme colours where
        scribbled, transparent elsewhere."""
        sc = self.texture.scribbles
        if sc is None:
            return None
        colours = np.zeros((256, 4), dtype=np.uint8)
        lib = self.texture.library.colours[:255]
        colours[1 : len(lib) + 1, :3] = lib
        colours[1 : len(lib) + 1, 3] = 255
        return np.ascontiguousarray(colours[sc[rows, cols]])

    def _padded_photo(self) -> np.ndarray | None:
        photo = self.model.photo
        if photo is None:
            return None
        w, h = self.extent
        ph, pw = photo.shape[:2]
        if (pw, ph) != (w, h) and self.photo_extent() == (float(pw), float(ph)):
            # Photo 1:1 from the origin: pad it to the render with its edge pixels.
            photo = np.pad(photo, ((0, h - ph), (0, w - pw), (0, 0)), mode="edge")
        return photo

    def fidelity(self) -> np.ndarray | None:
        """Per-cell CIEDE2000 difference render vs photo, (gh, gw) float32 (None without photo)."""
        if self._fidelity is None:
            photo = self._padded_photo()
            if photo is None:
                return None
            w, h = self.extent
            self._fidelity = fidelity_map(self.preview.image, photo, self.texture.grid.cells_shape)
            heat = heat_colours(self._fidelity)
            self.fidelity_pyramid = ZoomPyramid(heat, extent=(float(w), float(h)))
            self._summary = None
        return self._fidelity

    def fidelity_summary(self) -> str | None:
        """The whole texture against its photo: ``dE8 .., detail .., N bytes per area``."""
        if self._summary is None:
            photo = self._padded_photo()
            if photo is None or photo.shape[:2] != self.preview.image.shape[:2]:
                return None
            cost = texture_cost(self.texture)
            self._summary = (f"{fidelity(self.preview.image, photo).describe()}, "
                             f"{cost.area_bytes:,} bytes per area")
        return self._summary

    # -- files ---------------------------------------------------------------------
    def save(self, path: str | Path | None = None) -> Path:
        target = Path(path) if path else self.path
        if target is None:
            raise ValueError("no file name")
        self.model.save(target)
        self.path = target
        return target

    @classmethod
    def open(cls, path: str | Path, progress=None) -> EditorDocument:
        """Load a project file (raises TerrathemeError / CorruptFileError).

        ``progress(done, total)`` follows the first full render.
        """
        texture = load_checked_project(path)
        try:
            return cls(texture, path, progress)
        except TerrathemeError as exc:  # the preview's limit: name the project
            raise TerrathemeError(f"{path}: {exc}") from None
