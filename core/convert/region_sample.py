"""What a region's conversion chooses once, for the whole photo, read from its file.

:func:`core.convert.tiled.convert_file_tiled` converts a photo larger than
memory tile by tile with one choice for the whole region (issue 34), so it
gives the whole photo's texture, the same on every scheduler:

* :func:`fit_unsupervised_region`: the unsupervised model from the whole
  photo's k-means samples, drawn tile by tile in a first pass over the file
  (:func:`core.classify.unsupervised.window_samples`: the same samples, so
  the same themes as the whole-photo path); memory: one tile and the samples;
* :func:`region_sample`: full-resolution windows spread over the whole photo
  (a jittered ``grid x grid`` array, so a periodic mosaic is not sampled at one
  phase), each classified with the tiles' context and placed side by side as
  one sample image; the themes, the cell and the colour map's scale are
  chosen on it (:func:`sample_colour_scale`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

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
from terratheme.core.convert.colour_fit import ColourMapOptions, choose_colour_map, grid_window
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import Bands, image_info, read_region
from terratheme.core.io.tiles import Scheduler, TileWindow, run_tiles
from terratheme.core.model.grid import IndexGrid
from terratheme.core.render.renderer import RenderOptions, render_cells

if TYPE_CHECKING:
    from distributed import Client

#: side of one sample window (pixels): a multiple of every colour-map scale and cell tried
#: (48), so the sample's map blocks and cells are the region's
SAMPLE_PIECE = 384
#: windows per side of the sample (SAMPLE_GRID^2 windows, 1920^2 pixels in all)
SAMPLE_GRID = 5
#: window corners snap to multiples of this many pixels
SAMPLE_ALIGN = 48


@dataclass(frozen=True)
class FeatureSampleJob:
    """The tile job of :func:`fit_unsupervised_region`: one feature window's k-means samples.

    Attributes
    ----------
    options : UnsupervisedOptions
    size : (W, H) photo size
    stride : int
        Coarse pixels between samples, photo-wide (:func:`sampling_stride`).
    """

    options: UnsupervisedOptions
    size: tuple[int, int]
    stride: int

    def __call__(self, win: TileWindow, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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

    The feature windows and samples are those of
    :func:`core.classify.fit_unsupervised` on the whole photo, so the model
    (K, centres) is the same. With theme ``names`` and ``themes="auto"``, K
    never exceeds the number of names (as ``convert_photo`` does).

    Returns
    -------
    core.classify.UnsupervisedModel
    """
    opts = options or UnsupervisedOptions()
    info = image_info(path)
    fo = opts.features
    stride = sampling_stride(info.height, info.width, fo.scale, opts.max_samples)
    windows = feature_windows(info.height, info.width, opts.tile, fo.scale, fo.halo)
    chunks: list[np.ndarray] = []
    order: list[np.ndarray] = []

    def sink(_win: TileWindow, got: tuple[np.ndarray, np.ndarray]) -> None:
        chunks.append(got[0])
        order.append(got[1])

    run_tiles(path, FeatureSampleJob(opts, (info.width, info.height), stride), sink,
              windows=windows, scheduler=scheduler, progress=progress, bands=Bands.PHOTO)
    samples = np.concatenate(chunks).astype(np.float32)
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

    Attributes
    ----------
    windows : list of (x, y, w, h)
        Where each piece lies in the photo.
    places : list of (x, y)
        Where each piece lies in ``rgb``.
    rgb : (h, w, 3) uint8 ndarray
        The pieces side by side (the whole photo when it fits the budget).
    labels : (h, w) uint8 ndarray
        Their class values, classified with ``overlap`` pixels of context
        around each piece, as the tiles are.
    """

    windows: list[tuple[int, int, int, int]]
    places: list[tuple[int, int]]
    rgb: np.ndarray
    labels: np.ndarray


def sample_windows(size: tuple[int, int], piece: int | None = None, grid: int | None = None,
                   align: int = SAMPLE_ALIGN, seed: int = 0
                   ) -> list[list[tuple[int, int, int, int]]]:
    """About ``grid x grid`` windows of ``piece`` pixels spread over a photo, or the photo.

    The photo is divided into ``ny x nx`` cells (about ``grid^2``, shaped as
    the photo) and each window lies at a seeded random place inside its cell
    (a regular placement would sample a periodic mosaic at one phase only),
    its corner on a multiple of ``align``. The whole photo when it has no
    more pixels than the windows together.

    Parameters
    ----------
    size : (W, H)
    piece, grid : int, optional
        Default :data:`SAMPLE_PIECE` and :data:`SAMPLE_GRID`.

    Returns
    -------
    rows : list of rows of (x, y, w, h) windows, all of one size
    """
    w, h = size
    piece = SAMPLE_PIECE if piece is None else int(piece)
    grid = SAMPLE_GRID if grid is None else int(grid)
    if w * h <= (grid * piece) ** 2:
        return [[(0, 0, w, h)]]
    pw, ph = min(piece, w), min(piece, h)
    nx = int(np.clip(round(grid * np.sqrt(w / h)), 1, w // pw))
    ny = int(np.clip(grid * grid // nx, 1, h // ph))
    rng = np.random.default_rng(seed)

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
    return rows


def region_sample(path: str | os.PathLike, classify: Callable[[np.ndarray], np.ndarray],
                  overlap: int, rows: list[list[tuple[int, int, int, int]]] | None = None
                  ) -> RegionSample:
    """Read and classify the :func:`sample_windows` of a photo (one window at a time).

    Parameters
    ----------
    path : path-like
    classify : callable((h, w, C) ndarray) -> (h, w) integer ndarray
    overlap : int
        Context pixels read around each window for the classifier, then cropped.
    rows : rows of (x, y, w, h) windows of one size, optional
        Default :func:`sample_windows` of the photo.
    """
    info = image_info(path)
    rows = rows or sample_windows((info.width, info.height))
    side_w, side_h = rows[0][0][2:]
    rgb = np.zeros((len(rows) * side_h, len(rows[0]) * side_w, 3), np.uint8)
    labels = np.zeros(rgb.shape[:2], np.uint8)
    windows, places = [], []
    for j, row in enumerate(rows):
        for i, (x, y, ww, hh) in enumerate(row):
            rx, ry = max(0, x - overlap), max(0, y - overlap)
            rx1, ry1 = min(info.width, x + ww + overlap), min(info.height, y + hh + overlap)
            pixels = read_region(path, rx, ry, rx1 - rx, ry1 - ry, bands=Bands.PHOTO)
            got = np.asarray(classify(pixels)).reshape(pixels.shape[:2])
            core = (slice(y - ry, y - ry + hh), slice(x - rx, x - rx + ww))
            px, py = i * side_w, j * side_h
            rgb[py:py + hh, px:px + ww] = prepare_photo(pixels[core])[0]
            labels[py:py + hh, px:px + ww] = got[core]
            windows.append((x, y, ww, hh))
            places.append((px, py))
    return RegionSample(windows, places, rgb, labels)


def sample_colour_scale(sample: RegionSample, grid: IndexGrid, textures: list[np.ndarray],
                        render: RenderOptions, options: ColourMapOptions, reserved: int = 0
                        ) -> int:
    """The colour map's scale chosen on the sample (:func:`choose_colour_map`).

    Each window is rendered from the region's ``grid`` (only its vertices
    around the window, :func:`grid_window`) and placed as in the sample;
    ``reserved``: the sample's share of the area's bytes already spent (the
    packed grid).
    """
    shown = np.zeros_like(sample.rgb)
    for (x, y, w, h), (px, py) in zip(sample.windows, sample.places, strict=True):
        origin, block = grid_window(grid, TileWindow(x, y, w, h, x, y, w, h))
        shown[py:py + h, px:px + w] = render_cells(block, textures, grid.cell, region=(x, y, w, h),
                                                   options=render, origin=origin)
    return choose_colour_map(sample.rgb, shown, options, reserved=int(reserved)).colour_map.scale
