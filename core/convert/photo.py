"""Orthophoto -> thematic texture: the whole pipeline behind ``terratheme convert``.

Steps (each reports through ``progress(done, total)``, total = 100):

1. read the photo through OpenImageIO and its GeoTIFF georeference (``core.io.georef``);
2. classify it (``core.classify``): unsupervised with K chosen from the data,
   a fixed K, or supervised from a scribble mask (0 = unlabelled);
3. themes for the classes (``core.themes.from_photo``): cut from the photo and
   made tileable, or shipped themes by name;
4. labels -> theme indices -> the vertex grid (``core.convert.labels_to_grid``),
   the cell size chosen from the agreement target when ``cell="auto"``;
5. the project (``core.model.project.ThematicTexture``) with the photo, the
   scribbles, the georeference and the cell-size curve in its metadata.

:func:`write_outputs` then saves the project, a preview render cropped to the
photo (same pixel grid, so the same georeference: a GeoTIFF preview gets the
tags, a PNG a world file) and the vertex grid packed along a space-filling
curve (``core.packing``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.classify import classify_unsupervised, train_classifier
from core.classify.photo import prepare_photo
from core.convert.labels_to_grid import (
    DEFAULT_CELL_CANDIDATES,
    CellChoice,
    apply_lut,
    choose_cell_size,
    vote_grid,
)
from core.convert.labels_to_grid import agreement as measure
from core.errors import TerrathemeError
from core.io.georef import read_georeference, write_georeference
from core.io.images import read_image, write_image
from core.model.grid import IndexGrid
from core.model.project import ThematicTexture, save_project
from core.packing import pack
from core.render.project import photo_extent, render_georeference, render_project
from core.themes.from_photo import PatchOptions, ThemeMapping, themes_by_name, themes_from_photo

ProgressFn = Callable[[int, int], None]

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
        Square cell size in texels, or chosen from ``target_agreement``.
    themes : "auto", int, sequence of names or {class: name}
        "auto"/int: number of unsupervised classes (themes cut from the
        photo). Names: shipped themes; a list is assigned to the classes by
        colour (unsupervised K = auto, at most the number of names); a
        mapping names the class values (for scribbles).
    target_agreement : float
        Share of pixels whose label the grid must keep (``cell="auto"``).
    candidates : sequence of int
        Cell sizes tried by ``cell="auto"``.
    patch : PatchOptions
        Theme patch search.
    """
    cell: str | int = "auto"
    themes: str | int | Sequence[str] | Mapping[int, str] = "auto"
    target_agreement: float = 0.9
    candidates: tuple[int, ...] = DEFAULT_CELL_CANDIDATES
    patch: PatchOptions = field(default_factory=PatchOptions)


@dataclass(frozen=True)
class ConvertResult:
    """What :func:`convert_photo` made.

    Attributes
    ----------
    project : ThematicTexture
    labels : (H, W) uint8 ndarray
        The classifier's class values.
    confidence : (H, W) float32 ndarray
    mapping : ThemeMapping
        Themes and the class -> theme index table.
    choice : CellChoice or None
        The agreement curve when the cell size was chosen automatically.
    agreement : float
        Share of photo pixels whose theme the grid's label view keeps.
    """
    project: ThematicTexture
    labels: np.ndarray
    confidence: np.ndarray
    mapping: ThemeMapping
    choice: CellChoice | None
    agreement: float


def parse_themes(text: str) -> str | int | list[str] | dict[int, str]:
    """Parse ``--themes``: ``auto``, ``K``, ``name,name,...`` or ``1=name,2=name``."""
    text = text.strip()
    if not text:
        raise TerrathemeError("--themes is empty (use auto, a number, or theme names)")
    if text.lower() == "auto":
        return "auto"
    if text.isdigit():
        k = int(text)
        if not 1 <= k <= 255:
            raise TerrathemeError(f"--themes {k}: the number of themes must be 1..255")
        return k
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if all("=" in p for p in parts):
        out: dict[int, str] = {}
        for p in parts:
            key, name = (s.strip() for s in p.split("=", 1))
            if not key.isdigit() or not 1 <= int(key) <= 255:
                raise TerrathemeError(f"--themes {p!r}: class must be a number 1..255")
            out[int(key)] = name
        return out
    if any("=" in p for p in parts):
        raise TerrathemeError(f"--themes {text!r}: mix of names and class=name pairs")
    return parts


def _stage(progress: ProgressFn | None, start: int, span: int) -> ProgressFn | None:
    """A sub-progress mapped to ``[start, start + span]`` of the 100-step total."""
    if progress is None:
        return None

    def sub(done: int, total: int) -> None:
        progress(start + (span * done) // max(total, 1), 100)

    return sub


def _classify(photo, scribbles, themes, model, progress):
    if model is not None:
        return model.predict(photo, progress=progress)
    if scribbles is not None:
        model = train_classifier([(photo, scribbles)])
        return model.predict(photo, progress=progress)
    if isinstance(themes, int | str):
        return classify_unsupervised(photo, themes=themes, progress=progress)
    # Names: K from the data, but never more classes than names.
    n_names = len(themes)
    result = classify_unsupervised(photo, themes="auto", progress=progress)
    if len(np.unique(result.labels[result.labels > 0])) > n_names:
        result = classify_unsupervised(photo, themes=n_names, progress=progress)
    return result


def convert_photo(
    photo: np.ndarray,
    options: ConvertOptions = ConvertOptions(),
    *,
    scribbles: np.ndarray | None = None,
    model=None,
    metadata: dict | None = None,
    progress: ProgressFn | None = None,
) -> ConvertResult:
    """Turn a photo into a thematic texture.

    Parameters
    ----------
    photo : (H, W, 3|4) uint8/uint16 ndarray
        RGB(A); transparent pixels are no data (theme ``no data``).
    options : ConvertOptions
    scribbles : (H, W) integer ndarray, optional
        0 = unlabelled, k > 0 = class k: supervised classification.
    model : core.classify.Classifier, optional
        A trained classifier to use instead (``terratheme classify --model-out``).
    metadata : dict, optional
        Extra project metadata (source path, georeference, ...).
    progress : callable(done, total), optional

    Returns
    -------
    ConvertResult
    """
    rgb, _ = prepare_photo(photo)
    h, w = rgb.shape[:2]
    if scribbles is not None:
        scribbles = np.asarray(scribbles)
        if scribbles.ndim == 3 and scribbles.shape[2] == 1:
            scribbles = scribbles[:, :, 0]
        if scribbles.shape != (h, w):
            raise TerrathemeError(
                f"scribble mask is {scribbles.shape[1::-1]} but the photo is {w} x {h}"
            )
    if options.cell != "auto" and (not isinstance(options.cell, int) or options.cell < 1):
        raise TerrathemeError(f"cell must be 'auto' or a positive integer, got {options.cell!r}")
    # Classify the photo (40% of the progress).
    result = _classify(photo, scribbles, options.themes, model, _stage(progress, 0, 40))
    labels = result.labels
    # Themes: named shipped themes or patches cut from the photo (15%).
    if isinstance(options.themes, Mapping) or (
        not isinstance(options.themes, str | int)
    ):
        mapping = themes_by_name(rgb, labels, options.themes)
    else:
        mapping = themes_from_photo(rgb, labels, options=options.patch)
    if progress is not None:
        progress(55, 100)
    # Class values -> theme indices, then the cell size (35%) and the grid vote.
    theme_labels = apply_lut(labels, mapping.lut)
    choice = None
    if options.cell == "auto":
        choice = choose_cell_size(theme_labels, options.target_agreement,
                                  candidates=options.candidates,
                                  progress=_stage(progress, 55, 35))
        cell = choice.cell
    else:
        cell = (int(options.cell), int(options.cell))
    grid = IndexGrid(vote_grid(theme_labels, cell), cell)

    score = choice.agreement if choice is not None else measure(theme_labels, grid,
                                                                max_pixels=1 << 22)
    if progress is not None:
        progress(95, 100)
    meta = dict(metadata or {})
    meta.update({
        "created_by": "terratheme convert",
        "photo_size": [w, h],
        "classes": {str(c): mapping.library[int(mapping.lut[c])].name for c in mapping.classes},
        "agreement": score,
    })
    if choice is not None:
        meta["cell_choice"] = choice.as_dict()
    project = ThematicTexture(
        grid, mapping.library, meta,
        photo=rgb if rgb.size // 3 <= MAX_STORED_PHOTO else None,
        scribbles=None if scribbles is None else scribbles.astype(np.uint8),
    )
    if progress is not None:
        progress(100, 100)
    return ConvertResult(project, labels, result.confidence, mapping, choice, score)


def read_photo(path: str | os.PathLike) -> tuple[np.ndarray, dict]:
    """Read a photo and its georeference: ``((H, W, C) array, metadata dict)``."""

    photo = read_image(path)
    if photo.dtype not in (np.uint8, np.uint16):
        photo = read_image(path, dtype=np.uint8)
    meta: dict = {"source_photo": str(path)}
    geo = read_georeference(path)
    if geo:
        meta["georeference"] = geo
    return photo, meta


def render_preview(project: ThematicTexture, max_side: int = PREVIEW_MAX_SIDE) -> tuple[
    np.ndarray, tuple[int, int, int, int]
]:
    """The project rendered over the photo's extent (:func:`core.render.project.photo_extent`).

    Reduced when its long side exceeds ``max_side`` (overview renderer).

    Returns
    -------
    image : (h, w, 3) uint8 ndarray
    region : (x, y, w, h)
        The texels it covers.
    """
    w, h = photo_extent(project)
    scale = min(1.0, max_side / max(w, h))
    region = (0, 0, w, h)
    return render_project(project, region=region, scale=scale), region


def write_outputs(
    project: ThematicTexture,
    project_path: str | os.PathLike,
    *,
    preview_path: str | os.PathLike | None = None,
    packed_path: str | os.PathLike | None = None,
    preview_max_side: int = PREVIEW_MAX_SIDE,
) -> dict[str, Path]:
    """Save a project, its preview render and its packed index layer.

    Returns
    -------
    written : {"project": path, "preview": path, "packed": path, "world": path...}
    """
    written: dict[str, Path] = {}
    save_project(project_path, project)
    written["project"] = Path(project_path)
    if preview_path is not None:
        image, region = render_preview(project, preview_max_side)
        write_image(preview_path, image)
        written["preview"] = Path(preview_path)
        geo = render_georeference(project, region, image.shape[1::-1])
        for made in write_georeference(preview_path, geo):
            if made != Path(preview_path):
                written["preview_world_file"] = made
    if packed_path is not None:
        layer = pack(project.grid.indices, curve="auto")
        layer.save(packed_path)
        written["packed"] = Path(packed_path)
    return written
