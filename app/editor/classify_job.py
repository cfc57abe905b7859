"""Classification on a worker thread, with progress and Cancel.

The job runs the core classifier (unsupervised, or Extra-Trees trained on the
scribble layer) and converts its labels to a vertex grid
(``core.convert.labels_to_grid``) off the GUI thread; the window applies the result
as one undoable step. Cancel is cooperative: the progress callback raises
inside the classifier at its next tile, and a result that arrives after
Cancel is dropped.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from PySide6.QtCore import QObject, QThread, Signal
from terratheme.core.edit.uncertainty import scribble_classes
from terratheme.core.themes.library import Theme, ThemeLibrary

#: display colours of new class themes (matplotlib's tab10, as 8-bit RGB)
_QUALITATIVE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
                (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))


class Mode(Enum):
    UNSUPERVISED_MAP = "Unsupervised, map classes to the current themes"
    UNSUPERVISED_NEW = "Unsupervised, new themes cut from the photo"
    SCRIBBLES = "From scribbles (random forest)"
    AERIAL = "Shipped aerial model (building, land, road, vegetation, water)"


_LIVE: set[QThread] = set()


def keep_alive(thread: QThread) -> QThread:
    """Hold a reference to a parentless worker thread until it finishes.

    Workers have no Qt parent, so closing a window never destroys a thread
    that is still running (Qt aborts the process when that happens).
    """
    _LIVE.add(thread)
    thread.finished.connect(lambda: _LIVE.discard(thread))
    return thread


class Cancelled(Exception):
    """Raised inside the classifier's progress callback after Cancel."""


@dataclass
class ClassifyResult:
    """What the job hands back: the new grid indices and themes to append first.

    Attributes
    ----------
    indices : (gh, gw) vertex index grid
    new_themes : themes to append before applying ``indices``
    n_classes : classes the classifier knows
    confidence : (H, W) float32 ndarray, the photo's size, or None
        The winning class's vote share / posterior per photo pixel.
    class_weights : {class value: weight} or None
        Scribble runs: the model's class-prior weights (None without a correction).
    scribble_classes : frozenset of int
        Scribble runs: the class values painted in the scribbles trained on.
    """

    indices: np.ndarray
    new_themes: list[Theme]
    n_classes: int
    confidence: np.ndarray | None = None
    class_weights: dict[int, float] | None = None
    scribble_classes: frozenset[int] = field(default_factory=frozenset)


def class_themes(photo: np.ndarray, labels: np.ndarray, classes: tuple[int, ...],
                 taken: list[str], names: Mapping[int, str] | None = None
                 ) -> tuple[list[Theme], np.ndarray]:
    """Themes cut from the photo for every class (``core.convert.step.assign_themes``).

    Returns the themes (renamed where a name is taken, and given distinct
    display colours so the index map reads well; the texture keeps the
    photo's look) and the class -> position-in-that-list table.
    """
    from terratheme.core.convert.step import assign_themes

    mapping = assign_themes(photo[..., :3], labels, classes, names=names)
    out = []
    for i, theme in enumerate(mapping.library):
        name = theme.name
        while name.lower() in (t.lower() for t in taken):
            name += "'"
        taken.append(name)
        colour = _QUALITATIVE[i % len(_QUALITATIVE)]
        out.append(theme.with_(name=name, colour=colour))
    return out, mapping.lut.astype(np.int64)


def run_classification(mode: Mode, photo: np.ndarray, scribbles: np.ndarray | None,
                       library: ThemeLibrary, cell: tuple[int, int], grid_shape: tuple[int, int],
                       progress, class_weights: Mapping[int, float] | None = None,
                       position: bool = False) -> ClassifyResult:
    """Classify ``photo`` and convert the labels to a ``grid_shape`` vertex grid.

    ``class_weights`` (scribbles only): prior weights kept from an earlier run,
    passed to ``train_classifier``. ``position`` (scribbles only): the forest
    also uses where the strokes lie (``FeatureOptions.position``).
    """
    from terratheme.core.classify import SupervisedOptions, load_model
    from terratheme.core.convert.labels_to_grid import labels_to_grid
    from terratheme.core.convert.step import assign_themes, classify_photo
    from terratheme.core.errors import TerrathemeError

    # The one conversion step of core (core.convert.step), as terratheme convert runs it.
    if mode is Mode.SCRIBBLES:
        if scribbles is None or not scribbles.any():
            raise TerrathemeError("no scribbles: paint some with the Scribble tool (S) first")
        result, model = classify_photo(photo, scribbles=scribbles,
                                       supervised=SupervisedOptions().with_positions(position),
                                       class_weights=class_weights, progress=progress)
        weights = (None if model.class_weights is None else
                   dict(zip(model.classes, model.class_weights, strict=True)))
        painted = scribble_classes(scribbles)
        # Scribble value v marks theme v - 1.
        lut = np.clip(np.arange(256) - 1, 0, len(library) - 1)
        new_themes: list[Theme] = []
    elif mode is Mode.AERIAL:
        # The shipped classifier: new themes cut from the photo, named by its classes.
        weights, painted = None, frozenset()
        model = load_model("aerial")
        result, _ = classify_photo(photo, model=model, progress=progress)
        new_themes, lut = class_themes(photo, result.labels, result.classes,
                                       list(library.names), names=model.class_names)
        lut = lut + len(library)
    else:
        weights, painted = None, frozenset()
        result, _ = classify_photo(photo, progress=progress)
        labels, classes = result.labels, result.classes
        if mode is Mode.UNSUPERVISED_MAP:
            # Each class to its nearest current theme, by the rule convert --themes uses.
            lut = assign_themes(photo[..., :3], labels, classes, library).lut.astype(np.int64)
            new_themes = []
        else:
            new_themes, lut = class_themes(photo, labels, classes, list(library.names))
            lut = lut + len(library)
    # Lone specks removed, as convert does (core.convert.specks).
    grid = labels_to_grid(result.labels, cell, lut=lut, keep_specks=False)
    if grid.indices.shape != grid_shape:
        raise TerrathemeError(
            f"the photo ({photo.shape[1]} x {photo.shape[0]}) gives a {grid.indices.shape} grid "
            f"with cell {cell}; the project grid is {grid_shape}")
    return ClassifyResult(grid.indices, new_themes, len(result.classes),
                          np.asarray(result.confidence, np.float32), weights, painted)


class ClassifyJob(QThread):
    """Runs :func:`run_classification` on its own thread.

    Signals: ``progressed(done, total)``, ``succeeded(ClassifyResult)``,
    ``failed(str)``; after :meth:`cancel` none but ``finished`` is emitted.
    """

    progressed = Signal(int, int)
    succeeded = Signal(object)
    failed = Signal(str)

    def __init__(self, mode: Mode, photo, scribbles, library, cell, grid_shape,
                 parent: QObject | None = None, class_weights=None,
                 position: bool = False) -> None:
        super().__init__(parent)
        self.args = (mode, photo, scribbles, ThemeLibrary(library), cell, grid_shape)
        self.class_weights = class_weights
        self.position = position
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
                                        position=self.position)
        except Cancelled:
            return
        except Exception as exc:  # reported in the window, never a crash
            if not self.cancelled:
                self.failed.emit(str(exc) or type(exc).__name__)
            return
        if not self.cancelled:
            self.succeeded.emit(result)
