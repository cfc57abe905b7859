"""Orthophoto -> thematic texture: the whole pipeline behind ``terratheme convert``.

Read the photo and its georeference, classify it, choose themes and the cell, vote the
grid and fit the colour map (:mod:`.step`), then :func:`write_outputs` saves the
project, a georeferenced preview and the packed layer as one set.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from terratheme.core.classify.photo import prepare_photo
from terratheme.core.classify.samples import check_class_image
from terratheme.core.convert.cell_choice import (
    CONVERT_CELL_CANDIDATES,
    CellChoice,
    road_candidates,
)
from terratheme.core.convert.colour_fit import ColourMapOptions, FittedColourMap
from terratheme.core.convert.region_sample import photo_sample
from terratheme.core.convert.step import (
    budget_entry,
    classify_photo,
    cover_classes,
    detail_sigma,
    fit_colour_map,
    grid_and_colour,
    grid_budget,
    themes_and_cell,
)
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.atomic import file_set, write_bytes_atomic
from terratheme.core.io.codec import CODECS
from terratheme.core.io.georef import (
    read_georeference,
    stale_world_file,
    world_file_for,
    world_file_name,
    write_georeference,
    write_georeferenced,
)
from terratheme.core.io.images import Bands, read_image
from terratheme.core.model.project import ThematicTexture, save_project, shipped_colour_map
from terratheme.core.packing import pack
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.project import photo_extent, render_georeference, render_project
from terratheme.core.render.renderer import RenderOptions
from terratheme.core.themes.from_photo import ThemeMapping
from terratheme.core.themes.patch_search import PatchOptions

ProgressFn = Callable[[int, int], None]

#: file suffix of a colour map in each codec
CODEC_SUFFIX = {name: ext for name, (ext, _) in CODECS.items()}
#: photos up to this many pixels are stored in the project (the editor's overlay)
MAX_STORED_PHOTO = 40_000_000
#: preview renders larger than this on their long side are reduced (overview renderer)
PREVIEW_MAX_SIDE = 8192


@dataclass(frozen=True)
class ConvertOptions:
    """Options of :func:`convert_photo`.

    Attributes
    ----------
    cell : "auto" or int
        Square cell size in texels, or chosen from ``candidates`` so that the grid keeps
        ``target_agreement`` of the labels and ``class_target`` IoU of every class of at
        least 0.5% of the photo.
    themes : "auto", int, sequence of names or {class: name}
        "auto"/int: unsupervised classes, themes cut from the photo. Shipped theme names are
        assigned by appearance; a mapping names the class values (for scribbles).
    colour_map, boundary : ColourMapOptions, BoundaryOptions or None
        None: the paper's pure rule, the barycentric ramp.
    full_curve : bool
        Measure every candidate cell (``convert --curve``); False: stop at the first,
        from the largest down, that meets the targets (the same cell, faster).
    keep_specks : bool
        False: a vertex none of whose 8 neighbours shares its theme takes theirs.
    """

    cell: str | int = "auto"
    themes: str | int | Sequence[str] | Mapping[int, str] = "auto"
    target_agreement: float = 0.9
    class_target: float = 0.5
    candidates: tuple[int, ...] = CONVERT_CELL_CANDIDATES
    patch: PatchOptions = field(default_factory=PatchOptions)
    colour_map: ColourMapOptions | None = field(default_factory=ColourMapOptions)
    boundary: BoundaryOptions | None = field(default_factory=BoundaryOptions)
    full_curve: bool = False
    keep_specks: bool = False


@dataclass(frozen=True)
class ConvertResult:
    """What :func:`convert_photo` made.

    ``labels``: (H, W) uint8 class values; ``confidence``: (H, W) float32; ``choice``: the
    agreement curve when the cell was chosen; ``agreement``: share of photo pixels whose
    theme the grid's label view keeps; ``colour``: the colour map and its bytes.
    """

    project: ThematicTexture
    labels: np.ndarray
    confidence: np.ndarray
    mapping: ThemeMapping
    choice: CellChoice | None
    agreement: float
    colour: FittedColourMap | None = None


def _stage(progress: ProgressFn | None, start: int, span: int) -> ProgressFn | None:
    """A sub-progress mapped to ``[start, start + span]`` of the 100-step total."""
    if progress is None:
        return None

    def sub(done: int, total: int) -> None:
        progress(start + (span * done) // max(total, 1), 100)

    return sub


def convert_photo(
    photo: np.ndarray,
    options: ConvertOptions = ConvertOptions(),
    *,
    scribbles: np.ndarray | None = None,
    model=None,
    class_names: Mapping[int, str] | None = None,
    metadata: dict | None = None,
    progress: ProgressFn | None = None,
) -> ConvertResult:
    """Turn a photo into a thematic texture.

    Parameters
    ----------
    photo : (H, W, 3|4) uint8/uint16 ndarray
        RGB(A); transparent pixels are no data (theme ``no data``).
    scribbles : (H, W) integer ndarray, optional
        0 = unlabelled, k > 0 = class k: supervised classification.
    model : core.classify.Classifier, optional
        A trained or shipped classifier instead; its class names name the themes.
    class_names : {class: name}, optional
        With ``themes`` "auto": the themes' names (a legend's), before the model's own.
    """
    # Prepare: the 8-bit RGB every stage works on, the options checked.
    rgb, _ = prepared = prepare_photo(photo)
    h, w = rgb.shape[:2]
    if scribbles is not None:
        scribbles = check_class_image(scribbles, "scribble mask", (h, w))
    if options.cell != "auto" and (not isinstance(options.cell, int) or options.cell < 1):
        raise TerrathemeError(f"cell must be 'auto' or a positive integer, got {options.cell!r}")
    # Classify (35% of the progress): the alpha of ``photo`` marks no data.
    result, _ = classify_photo(prepared, themes=options.themes, scribbles=scribbles, model=model,
                               progress=_stage(progress, 0, 35))
    names = None
    if options.themes == "auto":
        names = {**(getattr(model, "class_names", None) or {}), **(class_names or {})} or None
    # A road theme keeps finer cells.
    listed = (list(options.themes.values()) if isinstance(options.themes, Mapping) else
              list(options.themes) if isinstance(options.themes, (list, tuple)) else [])
    candidates = road_candidates(options.candidates, [*(names or {}).values(), *listed])
    # Themes from each class's statistics, and the cell on their labels (15%); a photo
    # larger than a region's sample takes its themes from the sample, as its tiles would.
    sample = photo_sample(rgb, result.labels)
    themed = themes_and_cell(
        rgb, result.labels, result.classes, options.themes, cell=options.cell,
        target_agreement=options.target_agreement, class_target=options.class_target,
        candidates=candidates, patch=options.patch, names=names,
        full_curve=options.full_curve, keep_specks=options.keep_specks,
        detail=detail_sigma(options.colour_map),
        grid_bpp=grid_budget(options.colour_map, h * w),
        sample=sample)
    mapping = themed.mapping
    if progress is not None:
        progress(50, 100)
    # The grid (the chosen cell's, or voted at a given cell).
    render = RenderOptions(boundary=options.boundary)
    made = grid_and_colour(rgb, themed.theme_labels, mapping, cell=options.cell,
                           colour_map=None, render=render,
                           progress=_stage(progress, 50, 35), choice=themed.choice,
                           keep_specks=options.keep_specks,
                           grid_bpp=grid_budget(options.colour_map, h * w),
                           twin_labels=themed.twin_labels)
    mapping = made.mapping
    if sample is not None:
        # A class the grid shows that the sample's windows missed: windows moved onto it,
        # as a tiled conversion moves them.
        sample, mapping = cover_classes(
            sample, result.classes, mapping, made.grid, (w, h),
            lambda covering: photo_sample(rgb, result.labels, covering=covering),
            options.themes, patch=options.patch, names=names,
            detail=detail_sigma(options.colour_map))
    # The colour map, fitted to the render of the final themes.
    if options.colour_map is not None:
        made = replace(made, colour=fit_colour_map(
            rgb, made.grid, mapping.library, options.colour_map, render,
            packed=made.choice.packed_bytes if made.choice is not None else None))
    if progress is not None:
        progress(95, 100)
    meta = dict(metadata or {})
    meta.update({
        "created_by": "terratheme convert",
        "photo_size": [w, h],
        "classes": {str(c): mapping.library[int(mapping.lut[c])].name for c in mapping.classes},
        "agreement": made.agreement,
    })
    if made.choice is not None:
        meta["cell_choice"] = made.choice.as_dict()
    if options.boundary is not None:
        meta["render"] = {"boundary": asdict(options.boundary)}
    if made.colour is not None:
        meta["colour_map"] = {"codec": made.colour.codec, "bytes": len(made.colour.data),
                              **budget_entry(options.colour_map),
                              "colour_error": made.colour.colour_error,
                              "curve": [list(p) for p in made.colour.curve]}
    project = ThematicTexture(
        made.grid, mapping.library, meta,
        photo=rgb if rgb.size // 3 <= MAX_STORED_PHOTO else None,
        scribbles=None if scribbles is None else scribbles.astype(np.uint8),
        colour_map=None if made.colour is None else made.colour.colour_map,
    )
    if progress is not None:
        progress(100, 100)
    return ConvertResult(project, result.labels, result.confidence, mapping, made.choice,
                         made.agreement, made.colour)


def read_photo(path: str | os.PathLike) -> tuple[np.ndarray, dict]:
    """Read a photo and its georeference: ``((H, W, C) array, metadata dict)``."""

    photo = read_image(path, bands=Bands.PHOTO)
    if photo.dtype not in (np.uint8, np.uint16):
        photo = read_image(path, dtype=np.uint8, bands=Bands.PHOTO)
    meta: dict = {"source_photo": str(path)}
    geo = read_georeference(path)
    if geo:
        meta["georeference"] = geo
    return photo, meta


def render_preview(project: ThematicTexture, max_side: int = PREVIEW_MAX_SIDE) -> tuple[
    np.ndarray, tuple[int, int, int, int]
]:
    """``(image, region)``: the project rendered over the photo's extent, at most ``max_side``."""
    w, h = photo_extent(project)
    scale = min(1.0, max_side / max(w, h))
    region = (0, 0, w, h)
    return render_project(project, region=region, scale=scale), region


def colour_map_file(packed_path: str | os.PathLike, codec: str = "avif") -> Path:
    """Where a colour map in ``codec`` ships beside a packed layer: ``<stem>_colour.<ext>``."""
    target = Path(packed_path)
    return target.with_name(f"{target.stem}_colour{CODEC_SUFFIX[codec]}")


def output_files(project_path: str | os.PathLike, *,
                 preview_path: str | os.PathLike | None = None,
                 packed_path: str | os.PathLike | None = None) -> list[Path]:
    """Every file :func:`write_outputs` may write for these paths (to check before any work)."""
    paths = []
    if packed_path is not None:
        paths += [Path(packed_path), *(colour_map_file(packed_path, c) for c in CODEC_SUFFIX)]
    if preview_path is not None:
        world = world_file_name(preview_path)
        paths += [Path(preview_path), *([] if world is None else [world])]
    return [*paths, Path(project_path)]


def _old_colour_maps(project_path: Path, packed_path: str | os.PathLike | None,
                     keep: list[Path]) -> list[Path]:
    """Colour maps beside ``packed_path`` the replaced project shipped and the new set drops."""
    old = []
    for codec in CODEC_SUFFIX if packed_path is not None else ():
        path = colour_map_file(packed_path, codec)
        try:
            info = path.lstat()
        except OSError:
            continue
        if path in keep or not stat.S_ISREG(info.st_mode):
            continue
        data = shipped_colour_map(project_path, info.st_size)
        if data is not None and len(data) == info.st_size and data == path.read_bytes():
            old.append(path)
    return old


def write_outputs(
    project: ThematicTexture,
    project_path: str | os.PathLike,
    *,
    preview_path: str | os.PathLike | None = None,
    packed_path: str | os.PathLike | None = None,
    preview_max_side: int = PREVIEW_MAX_SIDE,
) -> dict[str, Path]:
    """Save a project, its preview render and its packed layer (+ colour map) as one set.

    All replaced or none, the project last (:func:`file_set`); a colour map the replaced
    project shipped and the new one lacks is removed with it. Returns ``{role: path}``.
    """
    # What goes where, in write order (the project names the others: last).
    plan: list[tuple[str, Path]] = []
    image = geo = layer = None
    if packed_path is not None:
        layer = pack(project.grid.indices, curve="auto")
        plan.append(("packed", Path(packed_path)))
        cmap = project.colour_map
        if cmap is not None and cmap.data is not None:
            plan.append(("colour_map", colour_map_file(packed_path, cmap.codec)))
    if preview_path is not None:
        image, region = render_preview(project, preview_max_side)
        geo = render_georeference(project, region, image.shape[1::-1])
        plan.append(("preview", Path(preview_path)))
        world = world_file_for(preview_path, geo)
        if world is not None:
            plan.append(("preview_world_file", world))
    plan.append(("project", Path(project_path)))

    def write(key: str, target: Path, paths: dict[str, Path]) -> None:
        if key == "packed":
            layer.save(target)
        elif key == "colour_map":
            write_bytes_atomic(target, project.colour_map.data)
        elif key == "preview":
            # zlib level 1: fast, barely larger (docs/decisions.md).
            # A GeoTIFF preview carries the tags; another's world file is a member of its own.
            write_georeferenced(target, image, {} if "preview_world_file" in paths else geo,
                                attributes={"png:compressionLevel": 1})
        elif key == "preview_world_file":
            write_georeference(paths["preview"], geo, world_file=target)
        else:
            save_project(target, project)

    finals = [path for _, path in plan]
    remove = _old_colour_maps(Path(project_path), packed_path, finals)
    if preview_path is not None and (stale := stale_world_file(preview_path, geo)):
        remove.append(stale)  # it placed the old preview; the new one has no georeference
    with file_set(finals, remove=remove), ThreadPoolExecutor(max_workers=1) as pool:
        # Each member written through its own path: the writers' atomic_path yields the
        # set's temporary, and their errors (a full disk) name the output, not a temporary.
        where = dict(plan)
        # The preview PNG is encoded on a second thread while the rest is written
        # (zlib in both releases the GIL); all are written before the set is renamed.
        beside = pool.submit(write, "preview", where["preview"], where) \
            if "preview" in where else None
        for key, target in where.items():
            if key != "preview":
                write(key, target, where)
        if beside is not None:
            beside.result()
    return dict(plan)
