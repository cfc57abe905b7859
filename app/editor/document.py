"""The open project as the window sees it: model, undo stack and the images it shows.

``EditorDocument`` owns the :class:`ThematicTexture`, the core
:class:`EditSession` (history kept in a QUndoStack instead), the live
:class:`RenderPreview` and three image pyramids (index colours, render,
photo). Core change events refresh only the changed vertices and the dirty
render cells, then ``regionChanged`` tells the canvases which texel
rectangle to repaint.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, QRectF, Signal
from PySide6.QtGui import QUndoStack

from app.editor.commands import AddThemeCommand, AtomCommand, ThemeCommand
from app.editor.imaging import ZoomPyramid
from app.editor.uncertainty import KeptPrior, next_kept_prior, scribble_classes, uncertain_mask
from core.edit.fidelity import fidelity_map, heat_colours
from core.edit.preview import RenderPreview
from core.edit.session import Atom, EditAtom, EditSession, GridChange
from core.edit.tools import capsule_footprint
from core.errors import TerrathemeError
from core.model.project import ThematicTexture, load_project, save_project
from core.themes.library import Theme


class EditorDocument(QObject):
    """A project open in the editor.

    Signals
    -------
    regionChanged(QRectF)
        Texels whose index colours or render changed.
    libraryChanged()
        A theme was added, renamed, recoloured or retextured.
    scribblesChanged()
        The scribble layer changed.
    confidenceChanged()
        A classification's confidence map was set or cleared.
    """

    regionChanged = Signal(QRectF)
    libraryChanged = Signal()
    scribblesChanged = Signal()
    confidenceChanged = Signal()

    def __init__(self, texture: ThematicTexture, path: str | Path | None = None,
                 progress=None) -> None:
        super().__init__()
        self.texture = texture
        self.path = Path(path) if path else None
        #: a project just started over a photo (classification replaces its themes)
        self.fresh_from_photo = False
        self.undo_stack = QUndoStack(self)
        self.session = EditSession(texture, keep_history=False)
        self.preview = RenderPreview(texture, progress=progress)
        self.render_pyramid = ZoomPyramid(self.preview.image)
        n, m = texture.grid.cell
        gh1, gw1 = texture.grid.indices.shape
        self.index_rgb = np.ascontiguousarray(texture.library.colours[texture.grid.indices])
        # Vertex (i, j) sits at texel (i*N, j*M): its pixel spans half a cell either side.
        self.index_pyramid = ZoomPyramid(self.index_rgb, extent=(gw1 * n, gh1 * m),
                                     origin=(-n / 2, -m / 2))
        self.photo_pyramid = None
        if texture.photo is not None:
            photo = np.ascontiguousarray(texture.photo[..., :3])
            self.photo_pyramid = ZoomPyramid(photo, extent=self.photo_extent())
        self._fidelity: np.ndarray | None = None
        self.fidelity_pyramid: ZoomPyramid | None = None
        # The last classification's confidence (not saved) and what it was computed for.
        self._confidence: np.ndarray | None = None
        self._confidence_for: tuple | None = None
        self._uncertain: np.ndarray | None = None
        #: class weights of the first scribble classification (see app.editor.uncertainty)
        self.kept_prior: KeptPrior | None = None
        self.session.subscribe(self._on_grid_change)
        self.scribblesChanged.connect(self._drop_prior_without_scribbles)

    # -- geometry ------------------------------------------------------------
    @property
    def extent(self) -> tuple[int, int]:
        """``(width, height)`` of the render in texels."""
        return self.texture.grid.texture_size

    def photo_extent(self) -> tuple[float, float]:
        """Texels the photo covers: 1:1 from the origin (the converter's convention),
        stretched over the render when its size differs by more than a cell."""
        ph, pw = self.texture.photo.shape[:2]
        w, h = self.extent
        n, m = self.texture.grid.cell
        if w - n < pw <= w and h - m < ph <= h:
            return float(pw), float(ph)
        return float(w), float(h)

    def to_vertex(self, x: float, y: float) -> tuple[float, float]:
        """Texel position -> vertex units (texel X sits at grid position X / N)."""
        n, m = self.texture.grid.cell
        return x / n, y / m

    # -- edits ---------------------------------------------------------------
    def _on_grid_change(self, change: GridChange) -> None:
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
        n, m = self.texture.grid.cell
        vr = QRectF((change.cols.start - 1) * n, (change.rows.start - 1) * m,
                    (change.cols.stop - change.cols.start + 2) * n,
                    (change.rows.stop - change.rows.start + 2) * m)
        self.regionChanged.emit(vr if region is None else vr.united(QRectF(*region)))

    def commit(self, atom: Atom | None, text: str) -> None:
        """Put an already-applied edit on the undo stack."""
        if atom is not None:
            self.undo_stack.push(AtomCommand(self, atom, text))

    def set_theme(self, k: int, theme: Theme) -> None:
        """Replace theme ``k`` and refresh what depends on it (no undo; see ThemeCommand)."""
        old = self.texture.library[k]
        self.texture.library.replace(k, theme)
        if theme.colour != old.colour:
            self.index_rgb[...] = self.texture.library.colours[self.texture.grid.indices]
            self.index_pyramid.update_region(0, 0, *self.index_rgb.shape[1::-1])
        if not np.array_equal(theme.texture, old.texture):
            self.preview.refresh_all()
            self.render_pyramid.update_region(0, 0, *self.extent)
            self._fidelity = None
        self.libraryChanged.emit()
        self.regionChanged.emit(QRectF(-1e9, -1e9, 2e9, 2e9))

    def change_theme(self, k: int, theme: Theme, text: str) -> None:
        """Rename / recolour / retexture theme ``k`` as an undoable step."""
        others = [n.lower() for i, n in enumerate(self.texture.library.names) if i != k]
        if theme.name.lower() in others:
            raise TerrathemeError(f"a theme called {theme.name!r} is already in the library")
        self.undo_stack.push(ThemeCommand(self, k, theme, text))

    def add_theme(self, theme: Theme) -> int:
        """Append a theme as one undo step; returns its index."""
        # Check first, so a refused theme leaves nothing on the undo stack.
        if theme.name.lower() in (n.lower() for n in self.texture.library.names):
            raise TerrathemeError(f"a theme called {theme.name!r} is already in the library")
        self.undo_stack.push(AddThemeCommand(self, theme, f"add theme {theme.name}"))
        return len(self.texture.library) - 1

    def append_theme(self, theme: Theme) -> int:
        """Append a theme (no undo; see AddThemeCommand)."""
        k = self.texture.library.append(theme)
        self.libraryChanged.emit()
        return k

    def remove_last_theme(self) -> Theme:
        """Remove the last theme (no undo); refused while the grid still uses it."""
        last = len(self.texture.library) - 1
        if last == 0 or int(self.texture.grid.indices.max()) >= last:
            raise TerrathemeError(
                f"theme {self.texture.library[last].name!r} is still painted on the grid"
            )
        theme = self.texture.library.remove_last()
        self.libraryChanged.emit()
        return theme

    # -- scribbles (training strokes for supervised classification) ----------
    def scribble_segment(self, a: tuple[float, float], b: tuple[float, float], radius: float,
                         value: int) -> EditAtom | None:
        """Paint ``value`` (theme + 1; 0 erases) into the scribble layer along the texel
        segment ``a``-``b`` with ``radius`` texels; returns the applied undo atom."""
        tex = self.texture
        if tex.photo is None:
            return None
        if tex.scribbles is None:
            tex.scribbles = np.zeros(tex.photo.shape[:2], dtype=np.uint8)
        # Texels -> photo pixels (1:1 unless the photo is stretched over the render).
        ew, eh = self.photo_extent()
        sx, sy = tex.photo.shape[1] / ew, tex.photo.shape[0] / eh
        fp = capsule_footprint(tex.scribbles.shape, (a[0] * sx, a[1] * sy),
                               (b[0] * sx, b[1] * sy), radius * sx)
        atom = EditAtom.record(tex.scribbles, fp, value)
        if atom is not None:
            atom.apply(tex.scribbles)
        return atom

    def scribble_rgba(self, rows: slice = slice(None), cols: slice = slice(None)
                      ) -> np.ndarray | None:
        """The scribble layer (or a block of it) as (h, w, 4) uint8: theme colours where
        scribbled, transparent elsewhere."""
        sc = self.texture.scribbles
        if sc is None:
            return None
        colours = np.zeros((256, 4), dtype=np.uint8)
        lib = self.texture.library.colours
        colours[1 : len(lib) + 1, :3] = lib
        colours[1 : len(lib) + 1, 3] = 255
        return np.ascontiguousarray(colours[sc[rows, cols]])

    # -- classifier confidence and the kept prior ------------------------------
    def _confidence_key(self) -> tuple:
        tex = self.texture
        photo = None if tex.photo is None else (id(tex.photo), tex.photo.shape)
        return (photo, tex.grid.indices.shape, tex.grid.cell)

    def set_confidence(self, confidence: np.ndarray | None) -> None:
        """Keep a classification's (H, W) confidence map (the photo's size); None clears it."""
        if confidence is not None:
            photo = self.texture.photo
            conf = np.asarray(confidence, np.float32)
            if photo is None or conf.shape != photo.shape[:2]:
                have = "no photo" if photo is None else f"a {photo.shape[1]} x {photo.shape[0]}"
                raise TerrathemeError(f"a {conf.shape[::-1]} confidence map does not fit "
                                      f"{have} photo")
            confidence = conf
        self._confidence = confidence
        self._confidence_for = None if confidence is None else self._confidence_key()
        self._uncertain = None
        self.confidenceChanged.emit()

    def confidence(self) -> np.ndarray | None:
        """The last confidence map, (H, W) float32; None once the photo or grid changed."""
        if self._confidence is not None and self._confidence_for != self._confidence_key():
            self.set_confidence(None)
        return self._confidence

    def uncertain(self) -> np.ndarray | None:
        """(H, W) bool: the least confident ``UNCERTAIN_SHARE`` of the photo, as regions."""
        conf = self.confidence()
        if conf is None:
            return None
        if self._uncertain is None:
            self._uncertain = uncertain_mask(conf)
        return self._uncertain

    def prior_for(self, scribbles: np.ndarray | None) -> dict[int, float] | None:
        """Class weights a scribble classification of ``scribbles`` should reuse, or None.

        A kept prior whose scribbled classes differ (a class added or erased)
        is dropped: the next run estimates afresh.
        """
        classes = scribble_classes(scribbles)
        if self.kept_prior is not None and not self.kept_prior.applies_to(classes):
            self.kept_prior = None
        return None if self.kept_prior is None else dict(self.kept_prior.weights)

    def remember_prior(self, classes: frozenset[int],
                       weights: dict[int, float] | None) -> None:
        """After a scribble classification: keep the first run's weights for its classes."""
        self.kept_prior = next_kept_prior(self.kept_prior, classes, weights)

    def _drop_prior_without_scribbles(self) -> None:
        if self.kept_prior is not None and not scribble_classes(self.texture.scribbles):
            self.kept_prior = None

    # -- fidelity ------------------------------------------------------------
    def fidelity(self) -> np.ndarray | None:
        """Per-cell CIEDE2000 difference render vs photo, (gh, gw) float32 (None without photo)."""
        tex = self.texture
        if tex.photo is None:
            return None
        if self._fidelity is None:
            w, h = self.extent
            photo = tex.photo[..., :3]
            ph, pw = photo.shape[:2]
            if (pw, ph) != (w, h) and self.photo_extent() == (float(pw), float(ph)):
                # Photo 1:1 from the origin: pad it to the render with its edge pixels.
                photo = np.pad(photo, ((0, h - ph), (0, w - pw), (0, 0)), mode="edge")
            self._fidelity = fidelity_map(self.preview.image, photo, tex.grid.cells_shape)
            heat = heat_colours(self._fidelity)
            self.fidelity_pyramid = ZoomPyramid(heat, extent=(float(w), float(h)))
        return self._fidelity

    # -- files ---------------------------------------------------------------
    def save(self, path: str | Path | None = None) -> Path:
        target = Path(path) if path else self.path
        if target is None:
            raise ValueError("no file name")
        save_project(target, self.texture)
        self.path = target
        self.undo_stack.setClean()
        return target

    @classmethod
    def open(cls, path: str | Path, progress=None) -> EditorDocument:
        """Load a project file (raises TerrathemeError / CorruptFileError).

        ``progress(done, total)`` follows the first full render.
        """
        return cls(load_project(path), path, progress)
