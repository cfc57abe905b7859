"""The shipped convolutional network (``--model aerial``), run from ONNX with OpenCV's dnn.

The network (``models/train_network.py``: a light U-Net trained on the CC0
Dubai photos) takes float32 RGB 0..255 (``N x 3 x h x w``, its normalisation
is inside the graph) and gives per-class softmax probabilities
(``N x C x h x w``). It runs on the photo box-averaged by an integer
``factor`` (``models.json`` ``scale`` = 1 / factor) for speed; its
probabilities are upsampled bilinearly to photo pixels (net pixel centres at
photo position ``(i + 0.5) * factor - 0.5``), and the arg-max is the label,
the winning probability the confidence.

The photo is cut into tiles of :attr:`NetworkOptions.tile` net pixels, each
run with :attr:`NetworkOptions.halo` net pixels of context on every side and
aligned to the network's poolings (``multiple``), so memory is bounded by the
tile and, with a halo as wide as the network's reach, tiles give the whole
photo's probabilities.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from terratheme.core.classify.photo import prepare_photo
from terratheme.core.classify.result import Classification, merged_class_names
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.archive import read_bounded

#: a network file larger than this is not one of ours
MAX_NETWORK_BYTES = 64 << 20


@dataclass(frozen=True)
class NetworkOptions:
    """How a photo is cut for the network.

    Attributes
    ----------
    tile : int
        Core of a tile, in net pixels (rounded down to a multiple of the
        network's ``multiple``); memory ~ 300 bytes per net pixel of a tile.
    halo : int
        Context on each side, in net pixels (rounded up likewise); 48 covers
        the trained network's reach up to float rounding.
    """

    tile: int = 768
    halo: int = 48


class NetworkClassifier:
    """An ONNX segmentation network with its class values and input scale.

    Parameters
    ----------
    path : path-like
        The ``.onnx`` file.
    classes : sequence of int
        Class value of each output channel, in channel order.
    scale : float
        The photo is box-averaged by ``round(1 / scale)`` before the network.
    multiple : int
        The network's input sides must be multiples of this (its poolings).

    Raises
    ------
    CorruptFileError
        The file is not an ONNX network OpenCV can run (one line naming it).
    TerrathemeError
        ``scale`` not 1 / an integer in 1..8, ``multiple`` not 1..64, no classes.
    """

    def __init__(self, path: str | os.PathLike, classes: Sequence[int], scale: float = 1.0,
                 multiple: int = 1, class_names: Mapping[int, str] | None = None,
                 options: NetworkOptions | None = None) -> None:
        factor = round(1.0 / scale) if scale > 0 else 0
        if not 1 <= factor <= 8 or abs(factor * scale - 1.0) > 1e-6:
            raise TerrathemeError(f"network scale {scale} is not 1 / an integer 1..8")
        if not 1 <= multiple <= 64:
            raise TerrathemeError(f"network multiple {multiple} is not 1..64")
        if not 1 <= len(classes) <= 256:
            raise TerrathemeError("a network needs 1..256 classes")
        self.path = Path(path)
        self.classes = tuple(int(c) for c in classes)
        self.factor = factor
        self.multiple = multiple
        self.options = options or NetworkOptions()
        self.class_names = None if class_names is None else {
            int(k): str(v) for k, v in class_names.items() if int(k) in self.classes}
        self._data = read_bounded(self.path, MAX_NETWORK_BYTES,
                                  f"{self.path}: not a network file")
        self._local = threading.local()
        self._net()  # refuse a bad file now, not at the first tile

    def __getstate__(self) -> dict:
        # cv2.dnn nets do not pickle (the Dask path ships the model): the bytes do.
        state = dict(self.__dict__)
        del state["_local"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._local = threading.local()

    def _net(self) -> cv2.dnn.Net:
        """This thread's network (a cv2.dnn.Net is not shared between threads)."""
        net = getattr(self._local, "net", None)
        if net is None:
            try:
                net = cv2.dnn.readNetFromONNX(np.frombuffer(self._data, np.uint8))
            except cv2.error:
                raise CorruptFileError(f"{self.path}: not an ONNX network OpenCV can run"
                                       ) from None
            self._local.net = net
        return net

    @property
    def context_pixels(self) -> int:
        """Photo pixels of context a label needs on each side (the halo, in photo pixels)."""
        return self._halo * self.factor

    @property
    def _halo(self) -> int:
        m = self.multiple
        return max(m, -(-self.options.halo // m) * m)

    def name_classes(self, names: Mapping[int, str]) -> None:
        """Name the classes after a legend; values the network does not give are skipped."""
        self.class_names = merged_class_names(self.classes, self.class_names, names)

    def save(self, path: str | os.PathLike) -> None:
        """Refused: a shipped network is kept as its ``.onnx`` file, not a model file."""
        raise TerrathemeError("the shipped network is not saved as a model file; "
                              "use --model aerial again")

    def _run(self, small: np.ndarray) -> np.ndarray:
        """Probabilities (h, w, C) float32 of a net-resolution float32 RGB window."""
        h, w = small.shape[:2]
        m = self.multiple
        ph, pw = -(-h // m) * m - h, -(-w // m) * m - w
        if ph or pw:
            # Reflected past the photo's end, as the whole photo would be.
            mode = cv2.BORDER_REFLECT_101 if min(h, w) > max(ph, pw) else cv2.BORDER_REPLICATE
            small = cv2.copyMakeBorder(small, 0, ph, 0, pw, mode)
        net = self._net()
        try:
            net.setInput(np.ascontiguousarray(small.transpose(2, 0, 1)[None]))
            out = net.forward()
        except cv2.error as exc:
            raise CorruptFileError(f"{self.path}: the network failed to run "
                                   f"({str(exc).strip().splitlines()[-1][:120]})") from None
        if out.ndim != 4 or out.shape[:2] != (1, len(self.classes)) or \
                out.shape[2:] != small.shape[:2]:
            raise CorruptFileError(f"{self.path}: the network gives shape {tuple(out.shape)}, "
                                   f"not 1 x {len(self.classes)} x {small.shape[0]} x "
                                   f"{small.shape[1]}")
        return out[0, :, :h, :w].transpose(1, 2, 0)

    def _tiles(self, height: int, width: int) -> Iterator[tuple[slice, slice, slice, slice]]:
        """Net-pixel (window rows, window cols, core rows, core cols) of each tile."""
        m, halo = self.multiple, self._halo
        tile = max(m, self.options.tile // m * m)
        for y0 in range(0, height, tile):
            for x0 in range(0, width, tile):
                y1, x1 = min(height, y0 + tile), min(width, x0 + tile)
                yield (slice(max(0, y0 - halo), min(height, y1 + halo)),
                       slice(max(0, x0 - halo), min(width, x1 + halo)),
                       slice(y0, y1), slice(x0, x1))

    def _tile_probabilities(self, rgb: np.ndarray, rows: slice, cols: slice,
                            core_rows: slice, core_cols: slice) -> np.ndarray:
        """Photo-pixel probabilities (h, w, C) float32 of one tile's core."""
        f = self.factor
        height, width = rgb.shape[:2]
        block = rgb[rows.start * f:rows.stop * f, cols.start * f:cols.stop * f]
        need = ((rows.stop - rows.start) * f, (cols.stop - cols.start) * f)
        if block.shape[:2] != need:
            # The photo's last odd rows / columns: repeated to whole net pixels.
            block = np.pad(block, ((0, need[0] - block.shape[0]), (0, need[1] - block.shape[1]),
                                   (0, 0)), mode="edge")
        small = cv2.resize(block, (need[1] // f, need[0] // f),
                           interpolation=cv2.INTER_AREA).astype(np.float32)
        probs = self._run(small)
        if f > 1:
            # Half-pixel centres, clamped at the window's edges: inside the photo the halo
            # holds the neighbours, at its edges the whole photo clamps the same way.
            probs = cv2.resize(probs, (probs.shape[1] * f, probs.shape[0] * f),
                               interpolation=cv2.INTER_LINEAR)
        oy, ox = (core_rows.start - rows.start) * f, (core_cols.start - cols.start) * f
        h = min(height, core_rows.stop * f) - core_rows.start * f
        w = min(width, core_cols.stop * f) - core_cols.start * f
        return probs[oy:oy + h, ox:ox + w]

    def _each_tile(self, rgb: np.ndarray, progress: Callable[[int, int], None] | None
                   ) -> Iterator[tuple[slice, slice, np.ndarray]]:
        """Photo rows, columns and probabilities of each tile, in order."""
        f = self.factor
        tiles = list(self._tiles(-(-rgb.shape[0] // f), -(-rgb.shape[1] // f)))
        for done, (rows, cols, core_rows, core_cols) in enumerate(tiles, 1):
            probs = self._tile_probabilities(rgb, rows, cols, core_rows, core_cols)
            ys = slice(core_rows.start * f, core_rows.start * f + probs.shape[0])
            xs = slice(core_cols.start * f, core_cols.start * f + probs.shape[1])
            yield ys, xs, probs
            if progress is not None:
                progress(done, len(tiles))

    def probabilities(self, photo: np.ndarray,
                      progress: Callable[[int, int], None] | None = None) -> np.ndarray:
        """(H, W, C) float32 probabilities of an (H, W, 3|4) photo, channels in
        ``self.classes`` order; ``progress(done, total)`` over tiles."""
        rgb, _ = prepare_photo(photo)
        out = np.empty(rgb.shape[:2] + (len(self.classes),), np.float32)
        for ys, xs, probs in self._each_tile(rgb, progress):
            out[ys, xs] = probs
        return out

    def predict(self, photo: np.ndarray,
                progress: Callable[[int, int], None] | None = None) -> Classification:
        """Classify a photo, tile by tile (memory: the labels, confidence and one tile).

        Returns
        -------
        Classification
            labels (H, W) uint8 of ``self.classes`` (0 where transparent);
            confidence the winning class's probability.
        """
        rgb, valid = prepare_photo(photo)
        labels = np.empty(rgb.shape[:2], np.uint8)
        confidence = np.empty(rgb.shape[:2], np.float32)
        lut = np.asarray(self.classes, np.uint8)
        for ys, xs, probs in self._each_tile(rgb, progress):
            best = probs.argmax(axis=2)
            labels[ys, xs] = lut[best]
            confidence[ys, xs] = np.take_along_axis(probs, best[:, :, None], axis=2)[:, :, 0]
        if valid is not None:
            labels[~valid] = 0
            confidence[~valid] = 0.0
        return Classification(labels, confidence, self.classes)

