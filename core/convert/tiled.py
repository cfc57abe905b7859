"""The vertex grid of a photo larger than memory: classify and vote tile by tile.

Each tile job owns a block of vertices, reads the pixels they vote over plus
``overlap`` of context, classifies, maps classes to themes, crops and votes; the grid
(a byte a vertex) is the only whole-image array. The grid equals :func:`vote_grid` of
the whole labels where the classifier's output with that context is the whole photo's,
and a cluster's result is the serial one, bit for bit.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from terratheme.core.classify import UnsupervisedModel
from terratheme.core.classify.photo import prepare_photo
from terratheme.core.convert.cell_choice import (
    CONVERT_CELL_CANDIDATES,
    cell_within_budget,
    choose_cell_size,
    packed_bytes,
    road_candidates,
)
from terratheme.core.convert.colour_fit import ColourMapOptions, colour_map_from_file
from terratheme.core.convert.labels_to_grid import apply_lut, grid_shape_for
from terratheme.core.convert.region_sample import (
    fit_unsupervised_region,
    region_sample,
    sample_colour_map,
)
from terratheme.core.convert.specks import SpeckStream
from terratheme.core.convert.step import (
    budget_entry,
    cover_classes,
    detail_sigma,
    grid_budget,
    keep_calm,
    sample_themes,
)
from terratheme.core.convert.tile_vote import (
    ClassifyFn,
    PredictLabels,
    VertexTile,
    VoteJob,
    vertex_tiles,
)
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.cluster import check_workers, warm_up
from terratheme.core.io.georef import read_georeference
from terratheme.core.io.images import Bands, image_info
from terratheme.core.io.tiles import Scheduler, run_tiles
from terratheme.core.model.grid import IndexGrid, validate_cell
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.renderer import RenderOptions, render_cells
from terratheme.core.themes.calm import ENERGY_REACH, CalmTwin, twin_vertices

if TYPE_CHECKING:
    from distributed import Client

#: context pixels around each tile (the forest's features reach 4 x 16 px plus smoothing)
DEFAULT_OVERLAP = 128


def grid_from_file(
    path: str | os.PathLike,
    cell: tuple[int, int] | int,
    classify: ClassifyFn,
    *,
    lut: Sequence[int] | np.ndarray | None = None,
    tile: int = 1024,
    overlap: int = DEFAULT_OVERLAP,
    scheduler: Scheduler | Client = Scheduler.SERIAL,
    progress: Callable[[int, int], None] | None = None,
    rows_final: Callable[[IndexGrid, int], None] | None = None,
    keep_specks: bool = True,
    calm: Sequence[CalmTwin] = (),
) -> IndexGrid:
    """The vertex grid of an image file, classified and voted tile by tile.

    ``classify`` maps an (h, w, C) tile to (h, w) class values (it must pickle on a cluster);
    ``lut`` (256,) maps class values to theme indices (default identity). ``tile`` is rounded
    to whole cells and read with ``overlap`` context pixels; every ``scheduler`` gives the same
    grid. ``rows_final(grid, n)`` is told after each tile how many first rows are final;
    ``keep_specks`` False makes lone vertices take their neighbours' theme; ``calm``: the
    table's calm twins, split off by each tile's pixels (``overlap`` then grows by their
    ``ENERGY_REACH``).
    """
    cell = (cell, cell) if isinstance(cell, int | np.integer) else tuple(cell)
    n, m = validate_cell(cell)
    if int(tile) < 1 or int(overlap) < 0:
        raise TerrathemeError(f"tile must be >= 1 and overlap >= 0, got {tile} and {overlap}")
    info = image_info(path)
    size = (info.width, info.height)
    table = None
    if lut is not None:
        table = np.asarray(lut)
        if table.shape != (256,):
            raise TerrathemeError(f"class-to-theme table must be 256 integers, got {table.shape}")
        table = table.astype(np.uint8)
    if calm:
        # The energy at a core pixel reaches the labels ENERGY_REACH away, and those need
        # the classifier's context (``overlap``) beyond them.
        overlap = int(overlap) + ENERGY_REACH
    tiles = vertex_tiles(size, (n, m), tile, overlap)
    rows, cols = grid_shape_for(info.width, info.height, (n, m))
    so_far = IndexGrid(np.zeros((rows, cols), np.uint8), (n, m))
    # With calm twins, the class grid and the twin-split vote beside it, joined into the
    # result as its rows finish (the class grid cleaned as on the whole photo).
    grid = so_far.indices if not calm else np.zeros_like(so_far.indices)
    split = np.zeros_like(grid) if calm else None
    specks = None if keep_specks else SpeckStream(grid)
    joined = 0

    def join(final: int) -> None:
        nonlocal joined
        if split is not None and final > joined:
            so_far.indices[joined:final] = twin_vertices(grid[joined:final],
                                                         split[joined:final], calm)
            joined = final

    def sink(win: VertexTile, block) -> None:
        (r0, r1), (c0, c1) = win.rows, win.cols
        if split is not None:
            block, split[r0:r1, c0:c1] = block
        grid[r0:r1, c0:c1] = block
        # The last tile of a band of rows finishes them (cleaned: all but the last).
        final = r1 if c1 == cols else r0
        if specks is not None:
            final = specks.advance(final)
        join(final)
        if rows_final is not None and final < rows:
            rows_final(so_far, final)

    run_tiles(path, VoteJob(classify, table, size, (n, m), tuple(calm)), sink, windows=tiles,
              scheduler=scheduler, progress=progress, bands=Bands.PHOTO)
    if specks is not None:
        specks.finish()
    join(rows)
    if rows_final is not None:
        rows_final(so_far, rows)
    return so_far


@dataclass(frozen=True)
class WarmKernels:
    """A warm-up task: the tile jobs' compiled code run once on tiny inputs, on a worker.

    Sent while the client cuts themes, so no tile pays numba's first-call load.
    ``render``: the colour-map stage's render style.
    """

    classify: ClassifyFn
    render: RenderOptions

    def __call__(self) -> None:
        # As a tile task runs: numba and OpenCV on this thread alone.
        import cv2
        import numba

        numba.set_num_threads(1)
        cv2.setNumThreads(1)
        pixels = np.zeros((64, 64, 3), np.uint8)
        self.classify(pixels)
        prepare_photo(pixels)
        render_cells(np.zeros((3, 3), np.uint8), [pixels[:8, :8]], (8, 8), options=self.render)


def convert_file_tiled(
    path: str | os.PathLike,
    model,
    cell: int | str,
    *,
    names: Sequence[str] | dict[int, str] | None = None,
    themes: str | int = "auto",
    target_agreement: float = 0.9,
    tile: int = 1024,
    overlap: int = DEFAULT_OVERLAP,
    scheduler: Scheduler | Client = Scheduler.SERIAL,
    progress: Callable[[int, int], None] | None = None,
    class_target: float = 0.5,
    candidates: Sequence[int] = CONVERT_CELL_CANDIDATES,
    colour_map: ColourMapOptions | None = ColourMapOptions(),
    boundary: BoundaryOptions | None = BoundaryOptions(),
    keep_specks: bool = False,
):
    """A project for a photo larger than memory, with a trained classifier or unsupervised.

    Themes, the cell and the map's scale are chosen once on the region's sample
    (:mod:`.region_sample`), then the grid and the colour map are made tile by tile; the
    project has no photo layer. ``model`` None: unsupervised themes on the whole photo's
    samples (``themes``: K or "auto"). ``cell``, ``names`` and the targets as
    :class:`ConvertOptions` (the cell also capped by a byte budget's grid share); ``tile``,
    ``overlap``, ``scheduler`` as :func:`grid_from_file`; ``progress(done, total)`` per pass.
    """
    info = image_info(path)
    if not isinstance(scheduler, Scheduler):
        # A cluster whose workers cannot run this code or read the photo: refused first;
        # the workers then import the tile jobs' code while the themes are fitted here.
        check_workers(scheduler, os.path.abspath(path))
        warm_up(scheduler, [__name__, colour_map_from_file.__module__])
    if model is None:
        # Unsupervised: the whole photo's k-means samples, drawn tile by tile (a first pass).
        if isinstance(names, dict):
            raise TerrathemeError("unsupervised themes are assigned by colour: give theme names "
                                  "as a list, or class=name pairs with a trained model")
        model = fit_unsupervised_region(path, themes, names, scheduler=scheduler,
                                        progress=progress)
        if names and len(names) < len(model.classes):
            raise TerrathemeError(f"{len(model.classes)} themes were asked for but only "
                                  f"{len(names)} names given")
        overlap = max(overlap, model.context_pixels)
    elif themes != "auto":
        raise TerrathemeError("themes K is for unsupervised classification; a trained model "
                              "gives its own classes")
    elif getattr(getattr(model.options, "features", None), "position", False):
        # Each tile would see its own positions, not the photo's.
        raise TerrathemeError("this classifier uses pixel positions (features.position): it "
                              "only classifies the whole photo it was trained on, not tiles")
    style = RenderOptions(boundary=boundary)
    if not isinstance(scheduler, Scheduler):
        # The workers load the tile jobs' kernels while the themes are cut here.
        warm_up(scheduler, [], [WarmKernels(PredictLabels(model), replace(style, threads=1))])
    # The region's sample: windows spread over the whole photo, classified as the tiles are
    # (an unsupervised model says how much context gives the whole photo's labels).
    context = getattr(model, "context_pixels", overlap)
    sample = region_sample(path, PredictLabels(model), min(overlap, context))
    unsupervised = isinstance(model, UnsupervisedModel)
    if names and unsupervised:
        # Names are assigned to the unsupervised themes by appearance.
        spec, class_names = list(names), None
    elif names:
        # Every class the model can give needs a name (list: in class order).
        named = dict(names) if isinstance(names, dict) else dict(zip(model.classes, names,
                                                                     strict=False))
        missing = [c for c in model.classes if c not in named]
        if missing or (not isinstance(names, dict) and len(names) != len(model.classes)):
            raise TerrathemeError(
                f"the classifier gives classes {list(model.classes)}: name each one "
                f"({', '.join(f'{c}=name' for c in model.classes)})"
            )
        spec, class_names = named, None
    else:
        # Themes cut from the photo, named by a shipped model's classes where it has them.
        spec, class_names = "auto", getattr(model, "class_names", None)
    # The themes, and with cell "auto" the cell size, chosen once on the sample: the themes
    # on its windows side by side, the cell on each window apart (the seams between them
    # are no borders of the photo: they would favour small cells).
    mapping = sample_themes(sample, model.classes, spec, names=class_names,
                            detail=detail_sigma(colour_map))
    choice = None
    if cell == "auto":
        # A theme named road, by the caller or the model, keeps finer cells, as on the whole
        # photo (not one the cut themes' appearance named: the whole photo's cell ignores it).
        given = names.values() if isinstance(names, dict) else names or (
            getattr(model, "class_names", None) or {}).values()
        candidates = road_candidates(candidates, given)
        theme_labels = apply_lut(sample.labels, mapping.lut)
        windows = sample.pieces(theme_labels)
        choice = choose_cell_size(windows, target_agreement,
                                  candidates=candidates, class_target=class_target,
                                  full_curve=False, keep_specks=keep_specks)
        # Under a byte budget the packed grid takes at most its share, as on the whole photo.
        bits = grid_budget(colour_map, info.width * info.height)
        if bits is not None:
            choice = cell_within_budget(sample.joined(theme_labels), choice, candidates, bits,
                                        keep_specks=keep_specks, windows=windows)
        cell = choice.cell[0]
    grid = grid_from_file(path, int(cell), PredictLabels(model), lut=mapping.lut,
                          tile=tile, overlap=overlap, scheduler=scheduler, progress=progress,
                          keep_specks=keep_specks, calm=mapping.calm)
    grid, mapping = keep_calm(grid, mapping, grid_budget(colour_map, info.width * info.height),
                              info.width * info.height)
    cell_windows = [list(w) for w in sample.windows]
    # A transparent photo has nothing to convert (as the whole photo's classifier says).
    no_data = int(mapping.lut[0])
    if no_data not in {int(mapping.lut[c]) for c in model.classes} and (
            grid.indices == no_data).all():
        raise TerrathemeError(f"{path}: photo is fully transparent: no pixel to classify")
    # A class the grid shows that the sample's windows missed: windows moved onto it.
    sample, mapping = cover_classes(
        sample, model.classes, mapping, grid, (info.width, info.height),
        lambda covering: region_sample(path, PredictLabels(model), min(overlap, context),
                                       covering=covering),
        spec, names=class_names, detail=detail_sigma(colour_map))
    fitted = None
    if colour_map is not None:
        # The map's scale and unsharp mask chosen on the sample, then the map itself tile by
        # tile; a byte budget covers the packed grid too, as on the whole photo.
        reserved = packed_bytes(grid) if colour_map.target is None else 0
        seen = sum(w * h for *_, w, h in sample.windows)
        share = min(1.0, seen / (info.width * info.height))
        chosen = sample_colour_map(sample, grid, mapping.library.textures, style, colour_map,
                                   reserved=int(round(reserved * share)))
        fitted = colour_map_from_file(path, grid, mapping.library.textures, chosen.coded_scale,
                                      render=style, options=colour_map, tile=tile,
                                      scheduler=scheduler, progress=progress, reserved=reserved,
                                      sharpen=chosen.sharpen,
                                      predicted=chosen.colours is not None)
    meta = {
        "source_photo": str(path), "created_by": "terratheme convert (tiled)",
        "photo_size": [info.width, info.height],
        "classes": {str(c): mapping.library[int(mapping.lut[c])].name for c in mapping.classes},
    }
    if choice is not None:
        meta["cell_choice"] = {**choice.as_dict(), "measured_on": cell_windows}
    if boundary is not None:
        meta["render"] = {"boundary": asdict(boundary)}
    if fitted is not None:
        meta["colour_map"] = {"codec": fitted.codec, "bytes": fitted.colour_map.nbytes,
                              **budget_entry(colour_map),
                              "scale_measured_on": [list(w) for w in sample.windows]}
    geo = read_georeference(path)
    if geo:
        meta["georeference"] = geo
    return ThematicTexture(grid, mapping.library, meta,
                           colour_map=None if fitted is None else fitted.colour_map)
