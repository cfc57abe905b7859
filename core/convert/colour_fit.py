"""The colour map of a converted photo: the gain that brings the render's colours to the photo's.

A class carries one texture, so the photo's slow colour changes are lost; the map
(:mod:`core.model.colour_map`) restores them (issues 13, 34). Default (``target`` None):
the area has a byte budget; for each of ``budget_scales`` the block gain ``photo /
render`` is coded at the highest quality that fits (:func:`fit_quality`), plain and, given
the render's grid, over the grid's prediction (:func:`grid_prediction`), rendered
through its 2x bicubic enlargement at even scales (:func:`budget_upsample`), and the scale
whose render scores best (:func:`budget_score`) is kept, then drawn at the unsharp mask of
``budget_sharpens`` that scores best (the block means and the codec soften its edges;
the mask costs no bytes). With a ``target``: the gain is
refined against its own bilinear upsampling and the coarsest of ``scales`` whose render
keeps dE8 under ``target`` is kept. Either way the map passes through its codec, so the
project renders what the packed output holds.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING

import cv2
import numpy as np
from terratheme.core.classify.photo import prepare_photo
from terratheme.core.convert.tile_vote import transparent
from terratheme.core.errors import TerrathemeError
from terratheme.core.fidelity.metrics import (
    COLOUR_SIGMA,
    Reference,
    colour_error,
    reference,
    structure_similarity,
)
from terratheme.core.io.cluster import map_ordered
from terratheme.core.io.codec import HEADER_SIZED
from terratheme.core.io.images import Bands, image_info
from terratheme.core.io.tiles import Scheduler, TileWindow, run_tiles
from terratheme.core.model.colour_map import (
    NEUTRAL,
    SHARPENS,
    ColourMap,
    TileBox,
    TileEncoder,
)
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.map_prediction import class_colours, class_prediction
from terratheme.core.render.colour_map import apply_colour_map, gain_image
from terratheme.core.render.renderer import RenderOptions, render_cells

if TYPE_CHECKING:
    from distributed import Client


#: the least bytes a byte budget gives an area
MIN_AREA_BYTES = 512

#: a predicted map's ``ColourMap.encode`` keywords: ``{"colours": (K, 3) uint8,
#: "prediction": (mh, mw, 3) uint8}`` (:mod:`core.model.map_prediction`)
Prediction = dict[str, np.ndarray]
#: ``predict(stored, scale)``: the prediction a map of stored gains at ``scale`` texels a
#: pixel may be coded over, or None
Predictor = Callable[[np.ndarray, int], "Prediction | None"]


def can_predict(shape: tuple[int, int], codec: str) -> bool:
    """Whether an ``(mh, mw)`` map in ``codec`` may ship predicted: one image of a codec
    whose header gives its size (docs/formats.md, predicted maps)."""
    return codec in HEADER_SIZED and ColourMap.fits_one_image(shape, codec)


def grid_prediction(stored: np.ndarray, grid: IndexGrid, n_themes: int, scale: int,
                    codec: str) -> Prediction | None:
    """The prediction a map of stored gains at ``scale`` may be coded over: each of the
    ``n_themes`` themes' mean gain drawn over ``grid`` (None where it may not ship
    predicted, :func:`can_predict`)."""
    if not can_predict(stored.shape[:2], codec):
        return None
    colours = class_colours(stored, grid.indices, grid.cell, scale, n_themes)
    return {"colours": colours, "prediction": class_prediction(
        grid.indices, grid.cell, colours, scale, stored.shape[:2])}


@dataclass(frozen=True)
class ColourMapOptions:
    """How the colour map of a conversion is made.

    ``target``: dE8 (mean CIEDE2000 after a sigma-8 blur) to reach at the coarsest of
    ``scales`` (texels per map pixel, coarsest first), refining the block gain ``iterations``
    times at codec ``quality``; None: the area (packed grid and map) gets ``budget`` bits per
    photo pixel and the best of ``budget_scales``, drawn at the best of ``budget_sharpens``
    (:func:`core.model.colour_map.sharpened`). ``codec``: see ``core.io.codec``.
    """

    target: float | None = None
    scales: tuple[int, ...] = (64, 32, 16, 8)
    codec: str = "avif"
    quality: int = 99
    iterations: int = 2
    budget: float = 0.04
    budget_scales: tuple[int, ...] = (16, 12, 8, 6, 4, 3)
    budget_sharpens: tuple[int, ...] = (0, 2, 4, 6)

    def __post_init__(self) -> None:
        for name in ("scales", "budget_scales"):
            got = getattr(self, name)
            if not got or any(int(s) < 1 for s in got):
                raise TerrathemeError(f"colour map {name} must be positive, got {got}")
        if not self.budget_sharpens or any(q not in SHARPENS for q in self.budget_sharpens):
            raise TerrathemeError(f"colour map budget_sharpens must be in {SHARPENS}, "
                                  f"got {self.budget_sharpens}")
        if self.target is not None and not self.target > 0:
            raise TerrathemeError(f"colour map target must be > 0, got {self.target}")
        if not self.budget > 0:
            raise TerrathemeError(f"colour map budget must be > 0 bits per pixel, "
                                  f"got {self.budget}")

    def area_bytes(self, pixels: int) -> int:
        """The area's budget bytes for ``pixels`` (at least ``MIN_AREA_BYTES``: codec headers)."""
        return max(MIN_AREA_BYTES, int(self.budget * pixels / 8))

    def map_bytes(self, pixels: int, reserved: int = 0) -> int:
        """The map's bytes under the budget for ``pixels`` photo pixels, ``reserved`` spent."""
        return max(0, self.area_bytes(pixels) - int(reserved))


@dataclass(frozen=True)
class FittedColourMap:
    """A colour map as stored and what it achieves.

    ``data``: the map in ``codec`` as packed, None for a map shipped in tiles
    (``colour_map.tiles``); ``colour_error``: estimated dE8 of the render with it;
    ``curve``: ``(scale, bytes, colour_error)`` of every scale tried.
    """

    colour_map: ColourMap
    data: bytes | None
    codec: str
    colour_error: float
    curve: tuple[tuple[int, int, float], ...]


def _padded(image: np.ndarray, h: int, w: int) -> np.ndarray:
    """``image`` cut or edge-extended to ``h x w``."""
    image = image[:h, :w]
    return cv2.copyMakeBorder(image, 0, h - image.shape[0], 0, w - image.shape[1],
                              cv2.BORDER_REPLICATE)


def fit_gain(photo: np.ndarray, render: np.ndarray, scale: int, iterations: int = 2
             ) -> np.ndarray:
    """The ``(mh, mw, 3)`` float32 gain at ``scale`` that maps ``render`` onto ``photo``.

    ``photo``: (h, w, 3) uint8 over the top-left of ``render`` (H, W, 3) uint8, the full
    texture without a map; texels beyond the photo take its edge.
    """
    th, tw = render.shape[:2]
    mh, mw = ColourMap.shape_for((tw, th), scale)
    ph, pw = mh * scale, mw * scale
    target = _padded(_padded(photo, th, tw), ph, pw).astype(np.float32)
    base = _padded(render, ph, pw).astype(np.float32)
    size = (mw, mh)

    def blocks(img: np.ndarray) -> np.ndarray:
        return cv2.resize(img, size, interpolation=cv2.INTER_AREA)

    want = blocks(target)
    # Step 1: the block ratio.
    gain = want / np.maximum(blocks(base), 1.0)
    for _ in range(iterations):
        # Step 2: correct for what the bilinear upsampling of the gain shows.
        up = gain_image(ColourMap(_quantise(gain), scale), (0, 0, pw, ph), (pw, ph))
        gain *= want / np.maximum(blocks(base * up), 1.0)
    return gain.astype(np.float32)


def _quantise(gain: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(gain * NEUTRAL), 0, 255).astype(np.uint8)


def _quick_photo(photo: np.ndarray) -> tuple[int, Reference]:
    """The photo's side of :func:`_quick_error`: its quarter-resolution reference."""
    f = 4 if min(photo.shape[:2]) >= 64 else 1
    if f == 1:
        return 1, reference(photo, factors=())
    size = (max(1, photo.shape[1] // f), max(1, photo.shape[0] // f))
    small = cv2.resize(photo, size, interpolation=cv2.INTER_AREA)
    return f, reference(small, sigmas=(COLOUR_SIGMA / f,), factors=())


def _quick_error(quick: tuple[int, Reference], render: np.ndarray) -> float:
    """dE8 at a quarter of the resolution (the blur scaled with it) for the scale choice."""
    f, ref = quick
    if f == 1:
        return colour_error(render, ref)
    h, w = ref.rgb.shape[:2]
    small = cv2.resize(render, (w, h), interpolation=cv2.INTER_AREA)
    return colour_error(small, ref, sigma=COLOUR_SIGMA / f)


def budget_upsample(scale: int) -> int:
    """The enlargement a budget map coded at ``scale`` ships with: 2 at even scales, else 1.

    The bicubic 2x decode renders the map's edges (roads, shores, shadows) sharper than
    the renderers' bilinear alone, at no bytes (docs/decisions.md).
    """
    return 2 if int(scale) % 2 == 0 else 1


#: qualities a doubling of a map's bytes takes, about (AVIF and WebP of gain maps), for the
#: first steps of :func:`fit_quality`'s search
QUALITY_PER_DOUBLING = 17
#: encodes :func:`fit_quality` guides by the bytes before it bisects what is left
FIT_GUIDED_STEPS = 4


def fit_quality(gain: np.ndarray, scale: int, codec: str, budget: int, *, upsample: int = 1,
                texture_size: tuple[int, int] | None = None, guess: int = 50,
                predicted: Prediction | None = None) -> tuple[int, ColourMap] | None:
    """``(quality, map)``: the (mh, mw, 3) uint8 stored gain at the best quality fitting ``budget``
    (drawn ``upsample`` times finer over a ``texture_size`` texture; coded over the
    ``predicted`` colours and prediction when given).

    The highest quality 1..99 that fits, bytes taken to grow with quality: from ``guess``
    (where the caller expects it), each step encodes the quality where the log of the bytes,
    interpolated between the nearest qualities tried on either side of the budget (or
    stepped ``QUALITY_PER_DOUBLING`` per doubling from one), meets the budget, inside the
    bracket those qualities leave, until the fitting and the failing quality are
    neighbours (bisecting after ``FIT_GUIDED_STEPS``): a few encodes a scale, where a
    bisection of 1..99 takes seven. ``png`` has one size.
    None when not even quality 1 fits.
    """
    def encode(q: int) -> ColourMap:
        return ColourMap.encode(gain, int(scale), codec, q, upsample=upsample,
                                texture_size=texture_size, **(predicted or {}))

    if codec == "png":
        cmap = encode(50)
        return (50, cmap) if cmap.nbytes <= budget else None
    # fits: the highest quality known to fit and its map; fails: the lowest known not to.
    fits: tuple[int, ColourMap] | None = None
    fails: tuple[int, int] | None = None  # (quality, bytes)
    target = np.log2(max(budget, 1))
    q = int(np.clip(guess, 1, 99))
    for step in range(1, 100):
        cmap = encode(q)
        if cmap.nbytes <= budget:
            fits = (q, cmap)
        else:
            fails = (q, cmap.nbytes)
        lo = fits[0] + 1 if fits is not None else 1
        hi = fails[0] - 1 if fails is not None else 99
        if lo > hi:
            return fits
        # The next quality: where log bytes reach the budget, between the two sides when
        # both are known, else a step by the usual slope; kept inside [lo, hi].
        if fits is not None and fails is not None:
            f_bytes = np.log2(max(fits[1].nbytes, 1))
            span = np.log2(fails[1]) - f_bytes
            t = (target - f_bytes) / span if span > 0 else 0.5
            q = fits[0] + t * (fails[0] - fits[0])
        else:
            q, size = (fits[0], fits[1].nbytes) if fits is not None else fails  # type: ignore[misc]
            q = q + QUALITY_PER_DOUBLING * (target - np.log2(max(size, 1)))
        q = int(np.clip(np.rint(q), lo, hi))
        if step >= FIT_GUIDED_STEPS:
            # Past the guided steps, bisection: the bracket halves at each encode.
            q = (lo + hi) // 2
    return fits


def budget_score(photo: Reference, quick: tuple[int, Reference], shown: np.ndarray
                 ) -> tuple[float, float, float, float]:
    """``(score, s4, s8, dE8)``: ``score = (s4 + s8) / 2 - dE8 / 20``, higher better."""
    s4 = structure_similarity(shown, photo, 4)
    s8 = structure_similarity(shown, photo, 8)
    err = _quick_error(quick, shown)
    return (s4 + s8) / 2 - err / 20, s4, s8, err


def _budget_map(photo: np.ndarray, render: np.ndarray, options: ColourMapOptions,
                reserved: int, predict: Predictor | None) -> FittedColourMap:
    """The byte budget's search of :func:`choose_colour_map` (module docstring)."""
    h, w = photo.shape[:2]
    size = (render.shape[1], render.shape[0])
    budget = options.map_bytes(h * w, reserved)
    curve: list[tuple[int, int, float]] = []
    best: tuple[float, ColourMap, float] | None = None
    coarsest = max(int(s) for s in options.budget_scales)
    ref, quick = reference(photo, sigmas=(), factors=(4, 8)), _quick_photo(photo)
    # The quality to try first at each scale: the coarser scale's, less the bytes its map's
    # (s_prev / s)^2 times the pixels would take.
    guess = 50
    previous: tuple[int, int] | None = None
    for scale in sorted({int(s) for s in options.budget_scales}, reverse=True):
        # The block ratio alone: its refinement sharpens the map, which then codes worse.
        gain = _quantise(fit_gain(photo, render, scale, 0))
        upsample = budget_upsample(scale)
        if previous is not None:
            guess = round(previous[1] - 2 * QUALITY_PER_DOUBLING * np.log2(previous[0] / scale))
        fitted = fit_quality(gain, scale, options.codec, budget, upsample=upsample,
                             texture_size=size, guess=guess)
        if fitted is not None:
            previous = (scale, fitted[0])
            cmaps = [fitted[1]]
        elif scale != coarsest or best is not None:
            continue
        else:
            # Not even the coarsest map fits: it at the lowest quality, over the budget.
            cmaps = [ColourMap.encode(gain, scale, options.codec, 1, upsample=upsample,
                                      texture_size=size)]
        # The same gain coded over the grid's prediction, when there is one.
        predicted = None if predict is None else predict(gain, scale)
        if predicted is not None:
            over = fit_quality(gain, scale, options.codec, budget, upsample=upsample,
                               texture_size=size, guess=previous[1] if previous else guess,
                               predicted=predicted)
            cmaps += [] if over is None else [over[1]]
        for cmap in cmaps:
            shown = apply_colour_map(np.ascontiguousarray(render[:h, :w]).copy(), cmap,
                                     (0, 0, w, h))
            score, _, _, err = budget_score(ref, quick, shown)
            curve.append((scale, cmap.nbytes, err))
            if best is None or score > best[0]:
                best = (score, cmap, err)
    plain_score, plain, plain_err = best  # type: ignore[misc]  (the coarsest scale gives one)
    # The chosen map drawn at each unsharp mask: the one that scores best ships (no bytes).
    shipped: tuple[float, ColourMap, float] | None = None
    for sharpen in options.budget_sharpens:
        if sharpen == plain.sharpen:
            drawn, got, got_err = plain, plain_score, plain_err
        else:
            drawn = plain.redrawn(sharpen, size)
            shown = apply_colour_map(np.ascontiguousarray(render[:h, :w]).copy(), drawn,
                                     (0, 0, w, h))
            got, _, _, got_err = budget_score(ref, quick, shown)
        if shipped is None or got > shipped[0]:
            shipped = (got, drawn, got_err)
    _, cmap, err = shipped  # type: ignore[misc]  (budget_sharpens is never empty)
    return FittedColourMap(cmap, cmap.data, options.codec, err, tuple(curve))


def choose_colour_map(photo: np.ndarray, render: np.ndarray,
                      options: ColourMapOptions = ColourMapOptions(), *,
                      reserved: int = 0, predict: Predictor | None = None
                      ) -> FittedColourMap:
    """The colour map of a conversion (module docstring).

    ``photo``: (h, w, 3) uint8; ``render``: (H, W, 3) uint8, the full texture without a
    map (H >= h, W >= w); ``reserved``: budget bytes already spent (the packed grid);
    ``predict``: what the render's grid predicts of a map (:func:`grid_prediction`), so a
    budget map may be coded over it where that scores better.
    """
    h, w = photo.shape[:2]
    if render.shape[0] < h or render.shape[1] < w:
        raise TerrathemeError(f"render {render.shape[1]} x {render.shape[0]} is smaller than "
                              f"the {w} x {h} photo")
    if options.target is None:
        return _budget_map(photo, render, options, reserved, predict)
    curve: list[tuple[int, int, float]] = []
    best: tuple[ColourMap, bytes, float] | None = None
    quick = _quick_photo(photo)
    for scale in options.scales:
        gain = fit_gain(photo, render, int(scale), options.iterations)
        cmap = ColourMap.encode(_quantise(gain), int(scale), options.codec, options.quality)
        # The photo's extent of the render, as a renderer shows it with this map.
        shown = apply_colour_map(np.ascontiguousarray(render[:h, :w]).copy(), cmap, (0, 0, w, h))
        err = _quick_error(quick, shown)
        curve.append((int(scale), cmap.nbytes, err))
        best = (cmap, cmap.data, err)
        if err <= options.target:
            break
    cmap, data, err = best  # type: ignore[misc]  (scales is never empty)
    return FittedColourMap(cmap, data, options.codec, err, tuple(curve))


def _block_sums(image: np.ndarray, s: int) -> np.ndarray:
    """Exact per-``s x s``-block channel sums (float64) of an image whose origin is on a block."""
    h, w = image.shape[:2]
    bh, bw = -(-h // s), -(-w // s)
    img = image[:, :, :3]
    if h % s or w % s:
        pad = np.zeros((bh * s, bw * s, 3), np.uint8)
        pad[:h, :w] = img
        img = pad
    rows = img.reshape(bh, s, bw * s * 3).sum(axis=1, dtype=np.uint32)
    return rows.reshape(bh, bw, s, 3).sum(axis=2, dtype=np.uint32).astype(np.float64)


def grid_window(grid: IndexGrid, win: TileWindow) -> tuple[tuple[int, int], np.ndarray]:
    """``(origin, block)``: the grid vertices a render of tile ``win``'s core needs.

    The cells under the core plus a ring of one vertex (the saddle rule's), so
    ``render_cells(block, ..., region=core, origin=origin)`` equals the whole grid's.
    """
    n, m = grid.cell
    rows, cols = grid.indices.shape
    r0, c0 = max(win.y // m - 1, 0), max(win.x // n - 1, 0)
    r1, c1 = min((win.y1 - 1) // m + 3, rows), min((win.x1 - 1) // n + 3, cols)
    return (r0, c0), np.ascontiguousarray(grid.indices[r0:r1, c0:c1])


@dataclass(frozen=True)
class BlockGainJob:
    """The tile job of :func:`colour_map_from_file`: the stored gain of its map pixels.

    Called ``job(win, pixels, (origin, block))`` with the tile's :func:`grid_window`: it
    holds no grid, so what a worker receives is set by the tile and the themes.
    """

    textures: list[np.ndarray]
    cell: tuple[int, int]
    render: RenderOptions
    scale: int

    def __call__(self, win: TileWindow, pixels: np.ndarray,
                 part: tuple[tuple[int, int], np.ndarray]) -> np.ndarray:
        if transparent(pixels):
            # No data: no photo colour to fit; the map leaves the render as it is.
            shape = (-(-win.h // self.scale), -(-win.w // self.scale), 3)
            return np.full(shape, NEUTRAL, np.uint8)
        # Step 1 on this tile's map pixels: the photo's sums over the render's, quantised.
        rgb, _ = prepare_photo(pixels)
        origin, block = part
        shown = render_cells(block, self.textures, self.cell, region=(win.x, win.y, win.w, win.h),
                             options=self.render, origin=origin)
        return _quantise(_block_sums(rgb, self.scale)
                         / np.maximum(_block_sums(shown, self.scale), 1.0))


def _encode_piece(item: tuple[TileBox, np.ndarray], encoder: TileEncoder
                  ) -> tuple[bytes, np.ndarray]:
    """One map tile on a cluster worker: ``item`` is ``(box, pixels)``."""
    return encoder(item[1])


def _box_name(box: TileBox) -> str:
    return f"of the colour map at ({box[1].start}, {box[0].start})"


@dataclass(frozen=True)
class ClusterTiles:
    """A :data:`core.model.colour_map.TileRunner` encoding map tiles on a dask cluster's workers."""

    client: Client

    def __call__(self, encoder: TileEncoder, boxes: list[TileBox],
                 piece: Callable[[TileBox], np.ndarray],
                 sink: Callable[[TileBox, tuple[bytes, np.ndarray]], None]) -> None:
        map_ordered(self.client, _encode_piece, boxes, encoder, sink, payload=piece,
                    describe=_box_name, group=1)


def colour_map_from_file(
    path: str | os.PathLike,
    grid: IndexGrid,
    textures: list[np.ndarray],
    scale: int,
    *,
    render: RenderOptions = RenderOptions(),
    options: ColourMapOptions = ColourMapOptions(),
    tile: int = 1024,
    scheduler: Scheduler | Client = Scheduler.SERIAL,
    progress: Callable[[int, int], None] | None = None,
    reserved: int = 0,
    sharpen: int = 0,
    predicted: bool = False,
) -> FittedColourMap:
    """The colour map of a photo larger than memory, tile by tile (the block gain only),
    drawn at unsharp mask ``sharpen`` and, when ``predicted``, coded over the grid's
    prediction where it can be (a budget map's choices, made on a sample).

    Each tile of whole map pixels returns their stored gain (:class:`BlockGainJob`), so
    memory is set by the tile and the map; pixels past the photo take the nearest one's
    gain. On a cluster (``scheduler`` a ``distributed.Client``) the map is the serial
    one, bit for bit. ``colour_error`` is NaN and ``curve`` empty.
    """
    tw, th = grid.texture_size
    mh, mw = ColourMap.shape_for((tw, th), scale)
    side = max(scale, (int(tile) // scale) * scale)
    stored = np.full((mh, mw, 3), NEUTRAL, np.uint8)
    info = image_info(path)
    # The tiles cover the photo: its map pixels, a top-left rectangle of the map.
    ch, cw = ColourMap.shape_for((info.width, info.height), scale)
    ch, cw = min(ch, mh), min(cw, mw)

    def sink(win: TileWindow, block: np.ndarray) -> None:
        # Every map pixel of a tile lies in that tile only: its gain is final.
        j, i = win.y // scale, win.x // scale
        bh, bw = block.shape[:2]
        stored[j:j + bh, i:i + bw] = block

    if not isinstance(scheduler, Scheduler):
        # On a cluster each task runs on one worker thread, its render too (same texels).
        render = replace(render, threads=1)
    job = BlockGainJob(list(textures), grid.cell, render, int(scale))
    run_tiles(path, job, sink, tile=side, scheduler=scheduler, progress=progress,
              bands=Bands.PHOTO, parts=partial(grid_window, grid))
    if (ch, cw) != (mh, mw):
        # Map pixels past the photo take the gain of the nearest covered one: outside a
        # rectangle that is the clamped position, the rectangle's edge extended.
        stored = np.pad(stored[:ch, :cw], ((0, mh - ch), (0, mw - cw), (0, 0)), mode="edge")
    # One image of the codec, or tiles when the map is beyond its single-image limit, encoded
    # on the workers on a cluster.
    run = None if isinstance(scheduler, Scheduler) else ClusterTiles(scheduler)
    quality, upsample, over = options.quality, 1, None
    if options.target is None:
        if predicted:
            over = grid_prediction(stored, grid, len(textures), int(scale), options.codec)
        quality = budget_quality(stored, int(scale), options.codec,
                                 options.map_bytes(info.width * info.height, reserved), over)
        upsample = budget_upsample(scale)
    cmap = ColourMap.encode(stored, int(scale), options.codec, quality, run=run,
                            upsample=upsample, sharpen=sharpen if options.target is None else 0,
                            texture_size=(tw, th), **(over or {}))
    return FittedColourMap(cmap, cmap.data, options.codec, float("nan"), ())


#: map pixels a side of the piece :func:`budget_quality` codes to choose the quality
QUALITY_PIECE = 1024


def budget_quality(stored: np.ndarray, scale: int, codec: str, budget: int,
                   predicted: Prediction | None = None) -> int:
    """The quality at which a whole map of stored gains fits ``budget`` bytes (at least 1;
    coded over ``predicted`` when given).

    On a larger map, chosen on its centre ``QUALITY_PIECE`` piece with the budget scaled.
    """
    mh, mw = stored.shape[:2]
    box = (slice(0, mh), slice(0, mw))
    if max(mh, mw) > QUALITY_PIECE:
        y, x = max(0, (mh - QUALITY_PIECE) // 2), max(0, (mw - QUALITY_PIECE) // 2)
        box = (slice(y, y + QUALITY_PIECE), slice(x, x + QUALITY_PIECE))
    piece = np.ascontiguousarray(stored[box])
    share = piece.shape[0] * piece.shape[1] / (mh * mw)
    part = None if predicted is None else {
        "colours": predicted["colours"],
        "prediction": np.ascontiguousarray(predicted["prediction"][box])}
    fitted = fit_quality(piece, scale, codec, int(budget * share), predicted=part)
    return 1 if fitted is None else fitted[0]
