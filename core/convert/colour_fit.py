"""The colour map of a converted photo: the gain that brings the render's colours to the photo's.

Issue 13: a class carries one texture, so the photo's slow colour changes
inside a class are lost and the render's colour layout is far from the
photo's (dE8 5.5 on held-out photos). The colour map (:mod:`core.model.colour_map`)
restores them at a small cost in bytes:

1. block means of photo and render over each map pixel's ``scale x scale``
   texels give the first gain, ``photo / render`` per channel;
2. the gain is refined (``iterations`` times) against the render multiplied
   by its own bilinear upsampling, since that is what a renderer shows;
3. it is quantised to the stored ``128 * gain`` and passed through the
   codec it ships in (JPEG XL at quality 99 by default: on the bundled and
   shared photos a near-lossless map at a coarse scale costs fewer bytes for
   the same colour error than a lossy one at a fine scale; WebP at quality 80
   and 1/8 gave dE8 1.89 at 5 kB per area, JPEG XL 99 gives 1.66 at 2.9 kB),
   so the project renders exactly what the packed output holds;
4. the scale: the coarsest of ``scales`` whose render keeps the colour error
   (:func:`core.fidelity.metrics.colour_error`, measured at a quarter of the
   resolution with the blur scaled alike) under ``target``, else the finest.

Issue 34 (the default, ``target`` None): the terrain engines' split. The map
carries everything above a few texels, roads and blocks where the photo has
them, and the themes only the fine detail (:func:`core.themes.detail.detail_texture`).
The area has a byte budget (``budget`` bits per photo pixel, grid included);
for each of ``budget_scales`` the block gain is coded at the highest quality
that fits (:func:`fit_quality`), and the scale whose render scores best
(:func:`budget_score`: structure at 1/4 and 1/8 against the colour error) is
kept: a fine map at a low quality carries more structure per byte than a
coarse near-lossless one (docs/decisions.md).
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
from terratheme.core.errors import TerrathemeError
from terratheme.core.fidelity.metrics import COLOUR_SIGMA, colour_error, structure_similarity
from terratheme.core.io.cluster import map_ordered
from terratheme.core.io.images import Bands, image_info
from terratheme.core.io.tiles import Scheduler, TileWindow, run_tiles
from terratheme.core.model.colour_map import NEUTRAL, ColourMap, TileBox, TileEncoder
from terratheme.core.model.grid import IndexGrid
from terratheme.core.render.colour_map import apply_colour_map, gain_image
from terratheme.core.render.renderer import RenderOptions, render_cells

if TYPE_CHECKING:
    from distributed import Client


#: the least bytes a byte budget gives an area
MIN_AREA_BYTES = 512


@dataclass(frozen=True)
class ColourMapOptions:
    """How the colour map of a conversion is made.

    Attributes
    ----------
    target : float or None
        A number: the colour error (mean CIEDE2000 after a sigma-8 blur) the
        map aims at, at the coarsest of ``scales`` (near-lossless ``quality``).
        None: the byte budget's search (module docstring).
    scales : tuple of int
        Texels per map pixel tried with a ``target``, coarsest first.
    codec : str
        How the map is stored in the packed output (``core.io.codec``: avif, jpegxl, webp,
        jpeg, png).
    quality : int
        Codec quality 1..100 with a ``target``.
    iterations : int
        Refinements of the block gain against its own upsampling (with a ``target``).
    budget : float
        Without a target: bits per photo pixel the area (packed grid and map) may take.
    budget_scales : tuple of int
        Texels per map pixel tried for the budget.
    """

    target: float | None = None
    scales: tuple[int, ...] = (64, 32, 16, 8)
    codec: str = "avif"
    quality: int = 99
    iterations: int = 2
    budget: float = 0.04
    budget_scales: tuple[int, ...] = (16, 12, 8, 6, 4)

    def __post_init__(self) -> None:
        for name in ("scales", "budget_scales"):
            got = getattr(self, name)
            if not got or any(int(s) < 1 for s in got):
                raise TerrathemeError(f"colour map {name} must be positive, got {got}")
        if self.target is not None and not self.target > 0:
            raise TerrathemeError(f"colour map target must be > 0, got {self.target}")
        if not self.budget > 0:
            raise TerrathemeError(f"colour map budget must be > 0 bits per pixel, "
                                  f"got {self.budget}")

    def area_bytes(self, pixels: int) -> int:
        """The area's bytes under the budget for ``pixels`` photo pixels (at least
        :data:`MIN_AREA_BYTES`: a tiny photo's map needs its codec's headers)."""
        return max(MIN_AREA_BYTES, int(self.budget * pixels / 8))

    def map_bytes(self, pixels: int, reserved: int = 0) -> int:
        """The map's bytes under the budget for ``pixels`` photo pixels, ``reserved`` spent."""
        return max(0, self.area_bytes(pixels) - int(reserved))


@dataclass(frozen=True)
class FittedColourMap:
    """A colour map as stored and what it achieves.

    Attributes
    ----------
    colour_map : ColourMap
        Decoded from ``data``.
    data : bytes or None
        The map in ``codec`` (what the packed output holds); None for a map
        beyond the codec's single-image limit, shipped in tiles
        (``colour_map.tiles``, :meth:`core.model.colour_map.ColourMap.encode`).
    codec : str
    colour_error : float
        Estimated dE8 of the render with this map.
    curve : tuple of (scale, bytes, colour_error)
        Every scale tried.
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

    Parameters
    ----------
    photo : (h, w, 3) uint8 ndarray
        The photo over the texture's top-left ``w x h`` texels.
    render : (H, W, 3) uint8 ndarray
        The full texture without a colour map (``H >= h``, ``W >= w``); texels
        beyond the photo take the photo's edge.
    scale : int
    iterations : int
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


def _quick_error(photo: np.ndarray, render: np.ndarray) -> float:
    """dE8 at a quarter of the resolution (the blur scaled with it) for the scale choice."""
    f = 4 if min(photo.shape[:2]) >= 64 else 1
    if f == 1:
        return colour_error(render, photo)
    size = (max(1, photo.shape[1] // f), max(1, photo.shape[0] // f))
    small = [cv2.resize(a, size, interpolation=cv2.INTER_AREA) for a in (photo, render)]
    return colour_error(small[1], small[0], sigma=COLOUR_SIGMA / f)


def fit_quality(gain: np.ndarray, scale: int, codec: str, budget: int
                ) -> tuple[int, ColourMap] | None:
    """The stored gain coded at the highest quality (1..99) whose bytes fit ``budget``.

    Bisection on the quality (bytes grow with it). ``png`` has no quality: its
    one size fits or not.

    Parameters
    ----------
    gain : (mh, mw, 3) uint8 ndarray
        Stored gains (``128 * gain``).
    scale : int
    codec : str
    budget : int
        Bytes the map may take.

    Returns
    -------
    (quality, ColourMap) or None
        None when not even quality 1 fits.
    """
    lo, hi, best = 1, 99, None
    while lo <= hi:
        q = (lo + hi) // 2
        cmap = ColourMap.encode(gain, int(scale), codec, q)
        if cmap.nbytes <= budget:
            best, lo = (q, cmap), q + 1
        else:
            hi = q - 1
        if codec == "png":
            break
    return best


def budget_score(photo: np.ndarray, shown: np.ndarray) -> tuple[float, float, float, float]:
    """How well a render with a map shows its photo: ``(score, s4, s8, dE8)``.

    ``score`` = mean of the structure at 1/4 and 1/8
    (:func:`core.fidelity.metrics.structure_similarity`) minus a tenth of the
    colour error (dE8 at a quarter of the resolution): one point of dE8 is
    worth 0.1 of structure. Higher is better.
    """
    s4 = structure_similarity(shown, photo, 4)
    s8 = structure_similarity(shown, photo, 8)
    err = _quick_error(photo, shown)
    return (s4 + s8) / 2 - err / 10, s4, s8, err


def _budget_map(photo: np.ndarray, render: np.ndarray, options: ColourMapOptions,
                reserved: int) -> FittedColourMap:
    """The byte budget's search of :func:`choose_colour_map` (module docstring)."""
    h, w = photo.shape[:2]
    budget = options.map_bytes(h * w, reserved)
    curve: list[tuple[int, int, float]] = []
    best: tuple[float, ColourMap, float] | None = None
    coarsest = max(int(s) for s in options.budget_scales)
    for scale in sorted({int(s) for s in options.budget_scales}, reverse=True):
        # The block ratio alone: its refinement sharpens the map, which then codes worse.
        gain = _quantise(fit_gain(photo, render, scale, 0))
        fitted = fit_quality(gain, scale, options.codec, budget)
        if fitted is not None:
            cmap = fitted[1]
        elif scale != coarsest or best is not None:
            continue
        else:
            # Not even the coarsest map fits: it at the lowest quality, over the budget.
            cmap = ColourMap.encode(gain, scale, options.codec, 1)
        shown = apply_colour_map(np.ascontiguousarray(render[:h, :w]).copy(), cmap, (0, 0, w, h))
        score, _, _, err = budget_score(photo, shown)
        curve.append((scale, cmap.nbytes, err))
        if best is None or score > best[0]:
            best = (score, cmap, err)
    _, cmap, err = best  # type: ignore[misc]  (the coarsest scale always gives a map)
    return FittedColourMap(cmap, cmap.data, options.codec, err, tuple(curve))


def choose_colour_map(photo: np.ndarray, render: np.ndarray,
                      options: ColourMapOptions = ColourMapOptions(), *,
                      reserved: int = 0) -> FittedColourMap:
    """The colour map of a conversion (see the module docstring).

    Parameters
    ----------
    photo : (h, w, 3) uint8 ndarray
    render : (H, W, 3) uint8 ndarray
        The full texture rendered without a colour map, ``H >= h, W >= w``.
    options : ColourMapOptions
    reserved : int
        Bytes of the area's budget already spent (the packed grid).

    Returns
    -------
    FittedColourMap
    """
    h, w = photo.shape[:2]
    if render.shape[0] < h or render.shape[1] < w:
        raise TerrathemeError(f"render {render.shape[1]} x {render.shape[0]} is smaller than "
                              f"the {w} x {h} photo")
    if options.target is None:
        return _budget_map(photo, render, options, reserved)
    curve: list[tuple[int, int, float]] = []
    best: tuple[ColourMap, bytes, float] | None = None
    for scale in options.scales:
        gain = fit_gain(photo, render, int(scale), options.iterations)
        cmap = ColourMap.encode(_quantise(gain), int(scale), options.codec, options.quality)
        # The photo's extent of the render, as a renderer shows it with this map.
        shown = apply_colour_map(np.ascontiguousarray(render[:h, :w]).copy(), cmap, (0, 0, w, h))
        err = _quick_error(photo, shown)
        curve.append((int(scale), cmap.nbytes, err))
        best = (cmap, cmap.data, err)
        if err <= options.target:
            break
    cmap, data, err = best  # type: ignore[misc]  (scales is never empty)
    return FittedColourMap(cmap, data, options.codec, err, tuple(curve))


def _block_sums(image: np.ndarray, s: int) -> np.ndarray:
    """Per-``s x s``-block channel sums of an image whose origin is on a block (float64).

    Exact: integer sums of uint8 (at most ``MAX_SCALE^2 * 255 < 2^32``), rows of
    a block first (contiguous), then its columns: 13x faster than summing a
    float64 copy over both axes at once (2.3 against 30.7 ms for a 1024^2 tile at
    scale 16), the same values.
    """
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
    """The vertices a render of tile ``win``'s core needs: ``(origin, block)``.

    The cells under the core plus one vertex on every side where the grid
    goes on (the saddle rule's ring), so
    ``render_cells(block, ..., region=core, origin=origin)`` equals the
    whole grid's render of the core (:func:`core.render.renderer.render_cells`).

    Returns
    -------
    origin : (row, col) of ``block[0, 0]`` in the grid
    block : (r, c) uint8 ndarray, at most ``(h/M + 4) x (w/N + 4)``
    """
    n, m = grid.cell
    rows, cols = grid.indices.shape
    r0, c0 = max(win.y // m - 1, 0), max(win.x // n - 1, 0)
    r1, c1 = min((win.y1 - 1) // m + 3, rows), min((win.x1 - 1) // n + 3, cols)
    return (r0, c0), np.ascontiguousarray(grid.indices[r0:r1, c0:c1])


@dataclass(frozen=True)
class BlockGainJob:
    """The tile job of :func:`colour_map_from_file`: the stored gain of its map pixels.

    Called ``job(win, pixels, (origin, block))`` with the tile's
    :func:`grid_window`: the job holds no grid, so what a worker receives
    is set by the tile and the themes, not the image.

    Attributes
    ----------
    textures : list of (h, w, 3) uint8 ndarray
    cell : (N, M)
    render : RenderOptions
    scale : int
        Texels per map pixel; tiles start on whole map pixels.
    """

    textures: list[np.ndarray]
    cell: tuple[int, int]
    render: RenderOptions
    scale: int

    def __call__(self, win: TileWindow, pixels: np.ndarray,
                 part: tuple[tuple[int, int], np.ndarray]) -> np.ndarray:
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
    """A :data:`core.model.colour_map.TileRunner` on a dask cluster: map tiles on its workers.

    The encoder goes to every worker once, each tile's pixels with its task
    (:func:`core.io.cluster.map_ordered`, a few in flight), so the client
    encodes none of the tiles (a 4096^2 JPEG XL tile is about 30 CPU s).
    """

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
) -> FittedColourMap:
    """The colour map of a photo larger than memory, tile by tile (the block gain of step 1).

    Tiles are whole map pixels; each reads its photo pixels, renders the same
    texels and returns the stored gain of its map pixels (photo sum over
    render sum, :class:`BlockGainJob`), so memory is set by the tile and the
    map (3 bytes a map pixel), not the photo. Map pixels beyond the photo
    (the last cells) take the nearest pixel's gain. The refinement of step 2
    needs every neighbour's gain and is not done here. On a cluster
    (``scheduler`` a ``distributed.Client``) every worker gets the themes
    once and each tile its window of the grid (:func:`grid_window`), so a
    worker's memory is set by the tile; the map is the serial one, bit for bit.
    ``reserved``: bytes of the area's budget already spent (the packed grid),
    as :func:`choose_colour_map`'s.

    Returns
    -------
    FittedColourMap
        ``colour_error`` is NaN (not measured on the whole photo); ``curve`` empty.
        A map beyond the codec's single-image limit is encoded tile by tile
        (:meth:`core.model.colour_map.ColourMap.encode`), on the cluster's
        workers when there is one (:class:`ClusterTiles`): the same bytes.
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
    quality = options.quality
    if options.target is None:
        quality = budget_quality(stored, int(scale), options.codec,
                                 options.map_bytes(info.width * info.height, reserved))
    cmap = ColourMap.encode(stored, int(scale), options.codec, quality, run=run)
    return FittedColourMap(cmap, cmap.data, options.codec, float("nan"), ())


#: map pixels a side of the piece :func:`budget_quality` codes to choose the quality
QUALITY_PIECE = 1024


def budget_quality(stored: np.ndarray, scale: int, codec: str, budget: int) -> int:
    """The quality at which a whole map of stored gains fits ``budget`` bytes (at least 1).

    Chosen by :func:`fit_quality` on the map, or on its centre
    :data:`QUALITY_PIECE`-pixel piece with the budget scaled by area when the
    map is larger (a region's map), so the work is bounded.
    """
    mh, mw = stored.shape[:2]
    piece, share = stored, 1.0
    if max(mh, mw) > QUALITY_PIECE:
        y, x = max(0, (mh - QUALITY_PIECE) // 2), max(0, (mw - QUALITY_PIECE) // 2)
        piece = np.ascontiguousarray(stored[y:y + QUALITY_PIECE, x:x + QUALITY_PIECE])
        share = piece.shape[0] * piece.shape[1] / (mh * mw)
    fitted = fit_quality(piece, scale, codec, int(budget * share))
    return 1 if fitted is None else fitted[0]
