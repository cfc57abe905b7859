"""What a region's conversion chooses once, for the whole photo (issue 34).

:func:`fit_unsupervised_region`: the whole photo's unsupervised model from its k-means
samples, drawn tile by tile from its file (the same samples, so the same themes).
:func:`region_sample`: jittered full-resolution windows over the photo, side by side as
one image, on which the themes, the cell and the colour map's scale are chosen;
:func:`photo_sample`: the same windows of a photo in memory, for the same themes.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import cv2
import numpy as np
from terratheme.core.classify.features import FeatureOptions, image_features, with_position
from terratheme.core.classify.photo import prepare_photo
from terratheme.core.classify.tiled import feature_windows, sampling_stride
from terratheme.core.classify.unsupervised import (
    UnsupervisedOptions,
    choose_themes,
    window_samples,
)
from terratheme.core.classify.unsupervised_model import UnsupervisedModel
from terratheme.core.convert.colour_fit import (
    ColourMapOptions,
    Prediction,
    can_predict,
    choose_colour_map,
    grid_window,
)
from terratheme.core.convert.tile_vote import transparent
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import Bands, image_info, read_windows
from terratheme.core.io.tiles import Scheduler, TileWindow, run_tiles
from terratheme.core.model.colour_map import NEUTRAL, ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.map_prediction import class_prediction, class_sums, mean_colours
from terratheme.core.render.renderer import RenderOptions, render_cells

if TYPE_CHECKING:
    from distributed import Client

#: side of one sample window (pixels): a multiple of every colour-map scale and cell tried
#: (48, and a byte budget's cells of 32), so the sample's map blocks and cells are the region's
SAMPLE_PIECE = 384
#: windows per side of the sample (SAMPLE_GRID^2 windows, 2688^2 pixels in all)
SAMPLE_GRID = 7
#: window corners snap to multiples of this many pixels (a byte budget's cells of 32, which
#: only count the grid's packed bytes there, may sit half a cell off the region's)
SAMPLE_ALIGN = 48
#: no-data pixels between two windows of the sample (each window's reflection): a theme patch
#: across them would hold more than ``1 - PatchOptions.inside`` (15%) of another class
SAMPLE_GAP = 48


@dataclass(frozen=True)
class FeatureSampleJob:
    """The tile job of :func:`fit_unsupervised_region`: one feature window's k-means samples.

    ``size``: the (W, H) photo; ``stride``: coarse pixels between samples (:func:`sampling_stride`).
    """

    options: UnsupervisedOptions
    size: tuple[int, int]
    stride: int

    def __call__(self, win: TileWindow, pixels: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray] | None:
        if transparent(pixels):
            return None
        fo: FeatureOptions = self.options.features
        rgb, valid = prepare_photo(pixels)
        _, _, feats = image_features(rgb, fo)
        feats = with_position(feats, (win.ry, win.rx), self.size[::-1], fo)
        if valid is not None:
            valid = valid[win.y - win.ry:win.y1 - win.ry, win.x - win.rx:win.x1 - win.rx]
        return window_samples(feats, win, valid, self.size[0], self.stride, self.options)


def fit_unsupervised_region(
    path: str | os.PathLike,
    themes: str | int = "auto",
    names: Sequence[str] | None = None,
    *,
    options: UnsupervisedOptions | None = None,
    scheduler: Scheduler | Client = Scheduler.SERIAL,
    progress: Callable[[int, int], None] | None = None,
) -> UnsupervisedModel:
    """The whole photo's unsupervised model, its samples drawn tile by tile from the file.

    The same K and centres as :func:`fit_unsupervised` on the whole photo; with ``names``
    and ``themes="auto"``, K never exceeds the names (as ``convert_photo``).
    """
    opts = options or UnsupervisedOptions()
    info = image_info(path)
    fo = opts.features
    stride = sampling_stride(info.height, info.width, fo.scale, opts.max_samples)
    windows = feature_windows(info.height, info.width, opts.tile, fo.scale, fo.halo)
    chunks: list[np.ndarray] = []
    order: list[np.ndarray] = []

    def sink(_win: TileWindow, got: tuple[np.ndarray, np.ndarray] | None) -> None:
        if got is None:
            return  # a transparent window: no sample
        chunks.append(got[0])
        order.append(got[1])

    run_tiles(path, FeatureSampleJob(opts, (info.width, info.height), stride), sink,
              windows=windows, scheduler=scheduler, progress=progress, bands=Bands.PHOTO)
    samples = np.concatenate(chunks).astype(np.float32) if chunks else np.zeros((0, 1))
    if len(samples) == 0:
        raise TerrathemeError(f"{path}: no opaque pixel on the sampling grid to fit themes on")
    # Row-major order of the photo, as the whole photo's sampling gives them to k-means.
    samples = samples[np.argsort(np.concatenate(order), kind="stable")]
    fitted = choose_themes(samples, opts, themes)
    if names and themes == "auto" and len(fitted[0]) > len(names):
        fitted = choose_themes(samples, opts, len(names))
    return UnsupervisedModel(*fitted, opts)


@dataclass(frozen=True)
class RegionSample:
    """Windows of a photo, side by side as one image, and their classes.

    ``windows``: each piece's (x, y, w, h) in the photo; ``places``: its (x, y) in ``rgb``;
    ``rgb``: (h, w, 3) uint8 pieces (the whole photo when it fits), ``gap`` pixels apart;
    ``labels``: (h, w) uint8 classes, classified with context around each piece as the
    tiles are, 0 (no data) in the gaps, where ``rgb`` mirrors the pieces (a blur there
    sees what it sees at the photo's edge); ``no_data``: whether the photo may have label 0
    (:func:`region_sample`: a piece has, or the file has alpha; :func:`photo_sample`: the
    photo has).
    """

    windows: list[tuple[int, int, int, int]]
    places: list[tuple[int, int]]
    rgb: np.ndarray
    labels: np.ndarray
    gap: int = 0
    no_data: bool = False

    def pieces(self, image: np.ndarray) -> list[np.ndarray]:
        """The windows' pieces of an image laid out as ``rgb`` (views)."""
        return [image[y:y + h, x:x + w] for (x, y), (*_, w, h)
                in zip(self.places, self.windows, strict=True)]

    def _per_row(self) -> int:
        """Pieces in each row of the layout."""
        return len(self.windows) // len({y for _, y in self.places})

    def joined(self, image: np.ndarray) -> np.ndarray:
        """An image laid out as ``rgb`` with its pieces side by side, without the gaps."""
        pieces, per = self.pieces(image), self._per_row()
        return np.concatenate([np.concatenate(pieces[j:j + per], axis=1)
                               for j in range(0, len(pieces), per)], axis=0)

    def joined_places(self) -> list[tuple[int, int]]:
        """Each piece's (x, y) in :meth:`joined`'s image."""
        per = self._per_row()
        return [(sum(w for *_, w, _ in self.windows[k - k % per:k]),
                 sum(self.windows[r][3] for r in range(0, k - k % per, per)))
                for k in range(len(self.windows))]


def sample_windows(size: tuple[int, int], piece: int = SAMPLE_PIECE, grid: int = SAMPLE_GRID,
                   align: int = SAMPLE_ALIGN, *, covering: Sequence[tuple[int, int]] = ()
                   ) -> list[list[tuple[int, int, int, int]]]:
    """Rows of about ``grid x grid`` (x, y, w, h) windows of ``piece`` pixels, or the whole photo.

    Each lies at a seeded random place in its cell of the photo (a periodic mosaic is not
    sampled at one phase), its corner on a multiple of ``align``. ``covering``: (x, y)
    pixels a window must be centred on (as near as the alignment allows); for each, the
    window of its cell (or of the nearest cell whose window has not moved) moves there.
    """
    w, h = size
    if w * h <= (grid * piece) ** 2:
        return [[(0, 0, w, h)]]
    pw, ph = min(piece, w), min(piece, h)
    nx = int(np.clip(round(grid * np.sqrt(w / h)), 1, w // pw))
    ny = int(np.clip(grid * grid // nx, 1, h // ph))
    rng = np.random.default_rng(0)

    def spot(g: int, n: int, side: int, length: int) -> int:
        lo, hi = g * side // n, (g + 1) * side // n
        start = lo + int(rng.integers(0, max(1, hi - lo - length + 1)))
        return min(side - length, (start // align) * align)

    rows = []
    for gy in range(ny):
        row = []
        for gx in range(nx):
            x = spot(gx, nx, w, pw)
            row.append((x, spot(gy, ny, h, ph), pw, ph))
        rows.append(row)
    moved: set[tuple[int, int]] = set()
    for sx, sy in covering:
        # Centred on the pixel: one holding it at its edge may miss the class around it.
        place = (_around(sx, pw, align, w), _around(sy, ph, align, h), pw, ph)
        if any(win == place for row in rows for win in row):
            continue
        # The pixel's own cell, else the nearest cell whose window is still where it was.
        cx, cy = min(nx - 1, sx * nx // w), min(ny - 1, sy * ny // h)
        free = [(gx, gy) for gy in range(ny) for gx in range(nx) if (gx, gy) not in moved]
        if not free:
            break
        gx, gy = min(free, key=lambda g: ((g[0] - cx) ** 2 + (g[1] - cy) ** 2, g[1], g[0]))
        moved.add((gx, gy))
        rows[gy][gx] = place
    return rows


def _around(at: int, length: int, align: int, side: int) -> int:
    """The aligned start of a ``length`` span about centred on ``at`` that holds it."""
    start = (at - length // 2) // align * align
    while start + length <= at:
        start += align
    return min(side - length, max(0, start))


def class_spots(sample: RegionSample, classes: Sequence[int], lut: np.ndarray,
                themes: np.ndarray, step: tuple[int, int], size: tuple[int, int]
                ) -> list[tuple[int, int]]:
    """The (x, y) pixels the sample's windows must hold so that every class the region
    shows has pixels in the sample (a class it misses would get a flat placeholder theme).

    ``classes``, ``lut``: the classes and their class -> theme table; ``themes``: (h, w)
    theme indices every ``step`` (x, y) pixels over the (W, H) photo ``size`` (a grid's
    vertices, or theme labels at step 1). A missing class with a theme in ``themes`` gets
    the centre of the ``SAMPLE_PIECE`` square holding most of it (first in raster order).
    """
    seen = np.bincount(sample.labels.ravel(), minlength=256) > 0
    box = (max(1, SAMPLE_PIECE // step[0]), max(1, SAMPLE_PIECE // step[1]))
    spots = []
    for c in classes:
        if c == 0 or seen[c]:
            continue
        mask = themes == lut[c]
        if not mask.any():
            continue
        # Counts of the class in a window-sized box around each point (exact in float32).
        counts = cv2.boxFilter(mask.astype(np.float32), -1, box, normalize=False,
                               borderType=cv2.BORDER_CONSTANT)
        vy, vx = np.unravel_index(int(np.argmax(counts)), counts.shape)
        spots.append((min(size[0] - 1, int(vx) * step[0]), min(size[1] - 1, int(vy) * step[1])))
    return spots


def covering_sample(sample: RegionSample, classes: Sequence[int], lut: np.ndarray,
                    themes: np.ndarray, step: tuple[int, int], size: tuple[int, int],
                    read: Callable[[list[tuple[int, int]]], RegionSample]) -> RegionSample:
    """The sample with windows moved onto (:func:`class_spots`) the classes ``themes``
    holds that it misses; ``read(covering)`` lays out windows centred on those pixels.
    The same sample when no class is missing; of the samples tried, the one missing
    fewest classes."""
    missing = class_spots(sample, classes, lut, themes, step, size)
    best, fewest = sample, len(missing)
    spots: list[tuple[int, int]] = []
    for _ in range(len(classes)):
        # A moved window may have held the only pixels of another class: looked at again.
        new = [p for p in missing if p not in spots]
        if not new:
            break
        spots += new
        sample = read(spots)
        missing = class_spots(sample, classes, lut, themes, step, size)
        if len(missing) < fewest:
            best, fewest = sample, len(missing)
    return best


def _lay_out(rows: list[list[tuple[int, int, int, int]]],
             piece_of: Callable[[int, int, int, int], tuple[np.ndarray, np.ndarray]]
             ) -> RegionSample:
    """Rows of :func:`sample_windows` side by side, ``piece_of(x, y, w, h)`` giving each
    window's (rgb, labels)."""
    side_w, side_h = rows[0][0][2:]
    half = SAMPLE_GAP // 2 if len(rows) * len(rows[0]) > 1 else 0
    step_w, step_h = side_w + 2 * half, side_h + 2 * half
    rgb = np.zeros((len(rows) * step_h, len(rows[0]) * step_w, 3), np.uint8)
    labels = np.zeros(rgb.shape[:2], np.uint8)
    windows, places = [], []
    no_data = False
    for j, row in enumerate(rows):
        for i, (x, y, ww, hh) in enumerate(row):
            piece, got = piece_of(x, y, ww, hh)
            px, py = i * step_w + half, j * step_h + half
            if half:
                piece = cv2.copyMakeBorder(piece, half, half, half, half, cv2.BORDER_REFLECT)
            rgb[py - half:py + hh + half, px - half:px + ww + half] = piece
            labels[py:py + hh, px:px + ww] = got
            no_data |= bool((got == 0).any())
            windows.append((x, y, ww, hh))
            places.append((px, py))
    return RegionSample(windows, places, rgb, labels, 2 * half, no_data)


def region_sample(path: str | os.PathLike, classify: Callable[[np.ndarray], np.ndarray],
                  overlap: int, *, covering: Sequence[tuple[int, int]] = ()) -> RegionSample:
    """Read and classify the :func:`sample_windows` of a photo (one opening, top to bottom).

    ``classify``: (h, w, C) -> (h, w) labels; ``overlap``: context pixels read around each
    window, then cropped; ``covering``: as :func:`sample_windows`. A single window has no
    ``SAMPLE_GAP`` around it. ``no_data``: also when the file has an alpha channel.
    """
    info = image_info(path)
    rows = sample_windows((info.width, info.height), SAMPLE_PIECE, SAMPLE_GRID,
                          covering=covering)
    # Each window with its context, read in order of their top rows (one decode of a JPEG).
    wins = sorted({win for row in rows for win in row}, key=lambda win: (win[1], win[0]))
    reads = [(max(0, x - overlap), max(0, y - overlap),
              min(info.width, x + ww + overlap), min(info.height, y + hh + overlap))
             for x, y, ww, hh in wins]
    pieces = {}
    with contextlib.closing(read_windows(path, [(rx, ry, rx1 - rx, ry1 - ry)
                                                for rx, ry, rx1, ry1 in reads],
                                         bands=Bands.PHOTO)) as got_pixels:
        for (x, y, ww, hh), (rx, ry, _, _), pixels in zip(wins, reads, got_pixels, strict=True):
            got = np.asarray(classify(pixels)).reshape(pixels.shape[:2])
            core = (slice(y - ry, y - ry + hh), slice(x - rx, x - rx + ww))
            # Transparent pixels take the nearest opaque colour in the read window.
            piece = (np.zeros((hh, ww, 3), np.uint8) if transparent(pixels)
                     else prepare_photo(pixels).rgb[core])
            pieces[(x, y, ww, hh)] = (piece, got[core])
    sample = _lay_out(rows, lambda x, y, ww, hh: pieces[(x, y, ww, hh)])
    # A file with alpha may hold transparent pixels the windows miss: they keep their theme.
    return replace(sample, no_data=sample.no_data or info.alpha_channel >= 0)


def photo_sample(rgb: np.ndarray, labels: np.ndarray, *,
                 covering: Sequence[tuple[int, int]] = ()) -> RegionSample | None:
    """The region sample of a classified photo in memory, so that its themes are cut where
    a tiled conversion of its file cuts them; None where the photo is its own sample.

    ``rgb``: (H, W, 3) uint8; ``labels``: (H, W) uint8 classes; ``covering``: as
    :func:`sample_windows`. ``no_data`` is the whole photo's: transparent pixels outside
    the windows keep their theme.
    """
    h, w = labels.shape
    if w * h <= (SAMPLE_GRID * SAMPLE_PIECE) ** 2:
        return None
    rows = sample_windows((w, h), SAMPLE_PIECE, SAMPLE_GRID, covering=covering)
    sample = _lay_out(rows, lambda x, y, ww, hh: (rgb[y:y + hh, x:x + ww],
                                                  labels[y:y + hh, x:x + ww]))
    return replace(sample, no_data=bool((labels == 0).any()))


@dataclass(frozen=True)
class SamplePrediction:
    """What the region's grid predicts of a map of the sample's joined windows
    (:data:`core.convert.colour_fit.Predictor`): each window's map pixels take the
    region map's prediction there, the theme colours from the sample's own stored gains.

    ``blocks``: each window's ``(x, y, w, h)`` in the region and its ``(x, y)`` in the
    joined image, on multiples of every map scale (:data:`SAMPLE_ALIGN`).
    """

    grid: IndexGrid
    n_themes: int
    codec: str
    blocks: tuple[tuple[tuple[int, int, int, int], tuple[int, int]], ...]

    def __call__(self, stored: np.ndarray, scale: int) -> Prediction | None:
        if not can_predict(stored.shape[:2], self.codec):
            return None
        grid, mh, mw = self.grid, *stored.shape[:2]
        shape = ColourMap.shape_for(grid.texture_size, scale)
        # Each window's map pixels: in the joined map, and where they lie in the region's.
        parts = []
        for (x, y, w, h), (jx, jy) in self.blocks:
            rows = min(-(-h // scale), mh - jy // scale, shape[0] - y // scale)
            cols = min(-(-w // scale), mw - jx // scale, shape[1] - x // scale)
            parts.append(((jy // scale, jx // scale), (y // scale, x // scale), rows, cols))
        # The theme colours over every window, then the prediction window by window.
        counts = np.zeros(self.n_themes, np.int64)
        sums = np.zeros((self.n_themes, 3), np.float64)
        for (jr, jc), origin, rows, cols in parts:
            got = class_sums(stored[jr:jr + rows, jc:jc + cols], grid.indices, grid.cell,
                             scale, self.n_themes, origin)
            counts, sums = counts + got[0], sums + got[1]
        colours = mean_colours(counts, sums)
        prediction = np.full((mh, mw, 3), NEUTRAL, np.uint8)
        for (jr, jc), (r0, c0), rows, cols in parts:
            prediction[jr:jr + rows, jc:jc + cols] = class_prediction(
                grid.indices, grid.cell, colours, scale, shape, (r0, r0 + rows, c0, c0 + cols))
        return {"colours": colours, "prediction": prediction}


def sample_colour_map(sample: RegionSample, grid: IndexGrid, textures: list[np.ndarray],
                      render: RenderOptions, options: ColourMapOptions, reserved: int = 0
                      ) -> ColourMap:
    """The colour map :func:`choose_colour_map` makes of the sample's windows: the region's
    map takes its scale, its unsharp mask and whether it is coded over the grid's
    prediction (:class:`SamplePrediction`).

    Each window rendered from the region's ``grid`` (:func:`grid_window`); ``reserved``:
    the sample's share of the bytes spent already.
    """
    shown = np.zeros_like(sample.rgb)
    for (x, y, w, h), (px, py) in zip(sample.windows, sample.places, strict=True):
        origin, block = grid_window(grid, TileWindow(x, y, w, h, x, y, w, h))
        shown[py:py + h, px:px + w] = render_cells(block, textures, grid.cell, region=(x, y, w, h),
                                                   options=render, origin=origin)
    predict = SamplePrediction(grid, len(textures), options.codec,
                               tuple(zip(sample.windows, sample.joined_places(), strict=True)))
    return choose_colour_map(sample.joined(sample.rgb), sample.joined(shown), options,
                             reserved=int(reserved), predict=predict).colour_map
