"""The project file: a thematic texture (grid + theme library + metadata) in one file.

A ``.ttproj`` is a ZIP of ``manifest.json``, ``grid.npy``, ``themes/KKK.npy``, the
optional layers and colour map (layout: docs/formats.md, "Projects"). Loading a
hostile file costs work bounded by its size (:mod:`core.io.archive`): every member
and manifest field is checked before it is read, damage is one ``CorruptFileError``
line, a newer version ``UnsupportedVersionError``. :func:`save_project` refuses
what :func:`load_project` would refuse, so every saved project loads.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.io.archive import (
    MAX_JSON_DEPTH,
    json_depth,
    open_archive,
    read_json_member,
    read_member,
    read_npy_member,
)
from terratheme.core.io.atomic import atomic_path
from terratheme.core.io.codec import CODECS, HEADER_SIZED, check_header_shape
from terratheme.core.io.georef import validate_georeference
from terratheme.core.io.inputs import check_input_file
from terratheme.core.model.colour_map import (
    ColourMap,
    check_sharpen,
    check_tile_members,
    check_upsample,
)
from terratheme.core.model.grid import MAX_THEMES, IndexGrid, validate_indices
from terratheme.core.model.layers import LAYER_BY_NAME, LAYERS, MAX_LAYER_PIXELS, check_layer
from terratheme.core.model.manifest import (
    BASE_VERSION,
    FORMAT_NAME,
    GRID_MEMBER,
    MANIFEST,
    MAX_TEXT,
    PREDICTED_MAP_VERSION,
    SHARPENED_MAP_VERSION,
    TILED_MAP_VERSION,
    UPSAMPLED_MAP_VERSION,
    check_manifest,
)
from terratheme.core.model.map_prediction import class_prediction
from terratheme.core.themes.library import Theme, ThemeLibrary

PROJECT_SUFFIX = ".ttproj"
#: most grid vertices a project holds (128 MiB of indices)
MAX_GRID_VERTICES = 1 << 27
#: longest side of a theme texture, in texels
MAX_THEME_SIDE = 4096
#: largest manifest (metadata included)
MAX_MANIFEST_BYTES = 4 << 20
#: most tiles of a tiled colour map (65536 tiles of 4096^2: a 3 TB map)
MAX_COLOUR_MAP_TILES = 1 << 16
#: members: manifest, grid, layers, themes, then the colour map's tiles
_MAX_MEMBERS = MAX_THEMES + 64 + MAX_COLOUR_MAP_TILES


@dataclass(eq=False)
class ThematicTexture:
    """A thematic texture: the index grid, its theme library and metadata.

    ``library[k]`` is the theme for grid index ``k`` (every index must have one);
    ``metadata`` is JSON (``source_photo``, ``georeference``, ...). The optional
    per-pixel layers (``photo`` ``(H, W, 3) uint8``, ``scribbles`` ``(H, W) uint8``,
    0 = unlabelled) are described by :data:`LAYERS` and checked on construction;
    ``colour_map`` is the gain every renderer applies.
    """

    grid: IndexGrid
    library: ThemeLibrary
    metadata: dict = field(default_factory=dict)
    photo: np.ndarray | None = None
    scribbles: np.ndarray | None = None
    colour_map: ColourMap | None = None

    def __post_init__(self) -> None:
        if len(self.library) == 0:
            raise TerrathemeError("a thematic texture needs at least one theme")
        validate_indices(self.grid.indices, n_themes=len(self.library))
        if not isinstance(self.metadata, dict):
            raise TerrathemeError(f"project metadata must be a dict, not "
                                  f"{type(self.metadata).__name__}")
        sizes = {"grid": self.grid.indices.shape}
        for spec in LAYERS:
            arr = getattr(self, spec.name)
            if arr is not None:
                arr = check_layer(spec, arr, sizes)
                setattr(self, spec.name, arr)
                sizes[spec.name] = arr.shape[:2]
        if self.colour_map is not None:
            self.colour_map.check_covers(self.grid.texture_size)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ThematicTexture):
            return NotImplemented

        def same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
            return (a is None and b is None) or (
                a is not None and b is not None and np.array_equal(a, b)
            )

        return (
            self.grid == other.grid
            and self.library == other.library
            and self.metadata == other.metadata
            and all(same(getattr(self, s.name), getattr(other, s.name)) for s in LAYERS)
            and self.colour_map == other.colour_map
        )


def _npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(arr), allow_pickle=False)
    return buf.getvalue()


def check_vertex_count(count: int) -> None:
    """Refuse a grid of ``count`` vertices a project file cannot hold (``MAX_GRID_VERTICES``)."""
    if count > MAX_GRID_VERTICES:
        raise TerrathemeError(f"grid of {count:,} vertices is over the "
                              f"limit of {MAX_GRID_VERTICES:,} a project file holds")


def _check_savable(project: ThematicTexture) -> None:
    """Refuse what load_project would refuse, before anything is written."""
    validate_indices(project.grid.indices, n_themes=len(project.library))
    check_vertex_count(project.grid.indices.size)
    for theme in project.library:
        h, w = theme.texture.shape[:2]
        if max(h, w) > MAX_THEME_SIDE:
            raise TerrathemeError(f"theme {theme.name!r}: texture {w} x {h} is over the "
                                  f"limit of {MAX_THEME_SIDE} texels a side")
        if len(theme.name) > MAX_TEXT or len(theme.source) > MAX_TEXT:
            raise TerrathemeError(f"theme {theme.name[:40]!r}: name or source longer than "
                                  f"{MAX_TEXT} characters")
    if "georeference" in project.metadata:
        validate_georeference(project.metadata["georeference"])
    cmap = project.colour_map
    if cmap is not None and cmap.tiles is not None and len(cmap.tiles) > MAX_COLOUR_MAP_TILES:
        raise TerrathemeError(f"colour map of {len(cmap.tiles):,} tiles is over the limit of "
                              f"{MAX_COLOUR_MAP_TILES:,} a project file holds")


def _map_colours(colours: object, codec: object, tiled: bool, n_themes: int, label: str
                 ) -> np.ndarray | None:
    """A predicted map's theme colours ``(n_themes, 3)`` uint8 from its manifest entry
    (None: not predicted), refused unless one ``[r, g, b]`` of integers 0..255 per theme
    on a map in one image of a codec whose header gives its size (so the prediction is
    made only for an image of the texture's map size)."""
    if colours is None:
        return None
    if (codec not in HEADER_SIZED or tiled or not isinstance(colours, list)
            or len(colours) != n_themes
            or not all(isinstance(c, list) and len(c) == 3
                       and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255
                               for v in c) for c in colours)):
        raise CorruptFileError(f"{label}: colour map colours must be one [r, g, b] of "
                               f"integers 0..255 for each of the {n_themes} themes, on a "
                               f"map in one {' or '.join(HEADER_SIZED)} image")
    return np.asarray(colours, np.uint8).reshape(n_themes, 3)


def _load_colour_map(zf: zipfile.ZipFile, entry: object, grid: IndexGrid,
                     path: Path, n_themes: int) -> ColourMap | None:
    """The colour map the manifest names, checked against the grid before decoding."""
    if entry is None:
        return None
    tiled = isinstance(entry, dict) and "tile" in entry
    if not isinstance(entry, dict) or not (tiled or isinstance(entry.get("member"), str)):
        raise CorruptFileError(f"{path}: bad colour_map entry in the manifest")
    scale, codec = entry.get("scale"), entry.get("codec")
    if isinstance(scale, bool) or not isinstance(scale, int) or not 1 <= scale <= 4096:
        raise CorruptFileError(f"{path}: colour map scale must be an integer 1..4096")
    upsample, sharpen = entry.get("upsample", 1), entry.get("sharpen", 0)
    try:
        check_upsample(upsample, scale=scale, coded=codec is not None)
        check_sharpen(sharpen, coded=codec is not None)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{path}: {exc}") from None
    shape = ColourMap.shape_for(grid.texture_size, scale)
    label = str(path)
    colours = _map_colours(entry.get("colours"), codec, tiled, n_themes, label)
    if tiled:
        return _load_tiled_colour_map(zf, entry, shape, label, (upsample, sharpen),
                                      grid.texture_size)
    if codec is None:
        pixels = read_npy_member(zf, entry["member"], label, dtypes=[np.uint8], ndims=[3],
                                 max_bytes=shape[0] * shape[1] * 3)
        return ColourMap(pixels, scale)
    if not isinstance(codec, str) or codec not in CODECS:
        raise CorruptFileError(f"{path}: unknown colour map codec {codec!r}")
    # The codec's bytes: at most the raw map's size (a compressed map is smaller).
    data = read_member(zf, entry["member"], label, max_bytes=shape[0] * shape[1] * 3 + 4096)
    try:
        predicted = {}
        if colours is not None:
            # The image's size first: the prediction is as large as the map it claims.
            check_header_shape(data, codec, shape)
            validate_indices(grid.indices, n_themes=n_themes)
            predicted = {"colours": colours, "prediction": class_prediction(
                grid.indices, grid.cell, colours, scale, shape)}
        return ColourMap.from_bytes(data, codec, scale, shape, upsample=upsample,
                                    sharpen=sharpen, texture_size=grid.texture_size,
                                    **predicted)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{path}: {entry['member']}: {exc}") from None


def _load_tiled_colour_map(zf: zipfile.ZipFile, entry: dict, shape: tuple[int, int],
                           label: str, drawing: tuple[int, int],
                           texture_size: tuple[int, int]) -> ColourMap:
    """A colour map shipped in tiles, every field checked before a tile is read;
    ``drawing``: its ``(upsample, sharpen)``."""
    tile, codec, names = entry.get("tile"), entry.get("codec"), entry.get("members")
    if not isinstance(codec, str) or codec not in CODECS:
        raise CorruptFileError(f"{label}: unknown colour map codec {codec!r}")
    try:
        check_tile_members(shape, tile, names)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{label}: {exc}") from None
    # Each tile's bytes: at most its raw size (a compressed tile is smaller).
    limit = min(tile, shape[0]) * min(tile, shape[1]) * 3 + 4096
    tiles = [read_member(zf, name, label, max_bytes=limit) for name in names]
    try:
        return ColourMap.from_tiles(tiles, codec, entry["scale"], shape, tile,
                                    upsample=drawing[0], sharpen=drawing[1],
                                    texture_size=texture_size)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{label}: colour map tiles: {exc}") from None


def _predicts(cmap: ColourMap, project: ThematicTexture) -> bool:
    """Whether the project's grid and themes predict what its predicted map was coded over
    (a reader makes the prediction from the grid it reads, one colour per theme)."""
    grid = project.grid
    if len(cmap.colours) != len(project.library) or grid.indices.max() >= len(cmap.colours):
        return False
    made = class_prediction(grid.indices, grid.cell, np.asarray(cmap.colours, np.uint8),
                            cmap.coded_scale, cmap.coded_shape)
    return np.array_equal(made, cmap.prediction)


def save_project(path: str | os.PathLike, project: ThematicTexture) -> None:
    """Write ``project`` to ``path`` (a ``.ttproj`` file) atomically.

    Anything :func:`load_project` would refuse raises, and nothing is written.
    """
    _check_savable(project)
    themes = []
    members: dict[str, bytes] = {GRID_MEMBER: _npy_bytes(project.grid.indices)}
    for k, theme in enumerate(project.library):
        member = f"themes/{k:03d}.npy"
        members[member] = _npy_bytes(theme.texture)
        themes.append(
            {"name": theme.name, "colour": list(theme.colour), "source": theme.source,
             "texture": member}
        )
    layers = []
    for spec in LAYERS:
        arr = getattr(project, spec.name)
        if arr is not None:
            members[spec.member] = _npy_bytes(arr)
            layers.append(spec.name)
    extra = {}
    cmap = project.colour_map
    version = BASE_VERSION
    if cmap is not None and cmap.tiles is not None:
        rows, cols = ColourMap.tile_counts(cmap.coded_shape, cmap.tile)
        names = [f"colour_map/{k // cols:03d}_{k % cols:03d}{CODECS[cmap.codec][0]}"
                 for k in range(rows * cols)]
        members.update(zip(names, cmap.tiles, strict=True))
        extra["colour_map"] = {"scale": cmap.coded_scale, "codec": cmap.codec,
                               "tile": cmap.tile, "members": names}
        version = TILED_MAP_VERSION
    elif cmap is not None:
        if cmap.colours is not None and not _predicts(cmap, project):
            # The grid changed under a predicted map: it ships as the pixels shown.
            cmap = ColourMap(cmap.pixels, cmap.scale)
        if cmap.data is not None:
            member = "colour_map" + CODECS[cmap.codec][0]
            members[member] = cmap.data
        else:
            member = "colour_map.npy"
            members[member] = _npy_bytes(cmap.pixels)
        extra["colour_map"] = {"scale": cmap.coded_scale, "codec": cmap.codec, "member": member}
    if cmap is not None and cmap.upsample > 1:
        extra["colour_map"]["upsample"] = cmap.upsample
        version = UPSAMPLED_MAP_VERSION
    if cmap is not None and cmap.sharpen:
        extra["colour_map"]["sharpen"] = cmap.sharpen
        version = SHARPENED_MAP_VERSION
    if cmap is not None and cmap.colours is not None:
        extra["colour_map"]["colours"] = [list(c) for c in cmap.colours]
        version = PREDICTED_MAP_VERSION
    manifest = {
        "format": FORMAT_NAME,
        "version": version,
        "cell": list(project.grid.cell),
        "grid_shape": list(project.grid.indices.shape),
        "themes": themes,
        "metadata": project.metadata,
        "layers": layers,
        **extra,
    }
    try:
        manifest_text = json.dumps(manifest, indent=1, allow_nan=False)
    except (TypeError, ValueError, RecursionError) as exc:
        raise TerrathemeError(f"project metadata is not JSON-serialisable: {exc}") from exc
    if len(manifest_text.encode()) > MAX_MANIFEST_BYTES:
        raise TerrathemeError(f"project metadata is too large (manifest over "
                              f"{MAX_MANIFEST_BYTES:,} bytes)")
    if json_depth(manifest) > MAX_JSON_DEPTH:
        raise TerrathemeError(f"project metadata nests deeper than {MAX_JSON_DEPTH - 2} levels")
    with atomic_path(path) as tmp:
        # Deflate level 1: photo and texture pixels pack as small as at 6, in less time.
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
            zf.writestr(MANIFEST, manifest_text)
            for member, data in members.items():
                zf.writestr(member, data)


def shipped_colour_map(path: str | os.PathLike, max_bytes: int) -> bytes | None:
    """The codec bytes of the colour map a saved project holds whole (what ``convert``
    ships beside its packed layer), or None: no such map, larger than ``max_bytes``,
    or not a readable project."""
    label = str(path)
    try:
        with open_archive(Path(path), label, kind="terratheme project",
                          max_members=_MAX_MEMBERS) as zf:
            entry = read_json_member(zf, MANIFEST, label,
                                     max_bytes=MAX_MANIFEST_BYTES).get("colour_map")
            if not isinstance(entry, dict) or entry.get("codec") not in CODECS \
                    or not isinstance(entry.get("member"), str):
                return None
            return read_member(zf, entry["member"], label, max_bytes=max_bytes)
    except (TerrathemeError, OSError, AttributeError):
        return None


def load_project(path: str | os.PathLike) -> ThematicTexture:
    """Read a ``.ttproj`` file written by :func:`save_project`.

    Work and memory are bounded by the file's size and the module's limits; every
    field is checked before the arrays it describes are read. Damage raises
    CorruptFileError, a newer format or unknown layer UnsupportedVersionError.
    """
    path = Path(path)
    if not path.exists():
        if path.is_symlink():
            check_input_file(path, "a project file")  # a symlink loop or a dangling link
        raise TerrathemeError(f"{path}: no such project file")
    label = str(path)
    zf = open_archive(path, label, kind="terratheme project", max_members=_MAX_MEMBERS)
    with zf:
        if MANIFEST not in zf.namelist():
            raise CorruptFileError(f"{path}: not a terratheme project (no manifest)")
        manifest = read_json_member(zf, MANIFEST, label, max_bytes=MAX_MANIFEST_BYTES)
        try:
            check_manifest(manifest)
        except (CorruptFileError, UnsupportedVersionError) as exc:
            raise exc.at(path) from None
        except TerrathemeError as exc:
            raise CorruptFileError(f"{path}: {exc}") from None
        # Arrays: each checked against its limit and the bytes present before it is read.
        indices = read_npy_member(zf, GRID_MEMBER, label, max_bytes=MAX_GRID_VERTICES,
                                  dtypes=[np.uint8], ndims=[2])
        if list(indices.shape) != manifest["grid_shape"]:
            raise CorruptFileError(f"{path}: {GRID_MEMBER} is {indices.shape[0]} x "
                                   f"{indices.shape[1]} but the manifest says "
                                   f"{manifest['grid_shape'][0]} x {manifest['grid_shape'][1]}")
        textures = [
            read_npy_member(zf, t["texture"], label, dtypes=[np.uint8], ndims=[3],
                            max_bytes=MAX_THEME_SIDE * MAX_THEME_SIDE * 3)
            for t in manifest["themes"]
        ]
        layers = {
            name: read_npy_member(zf, LAYER_BY_NAME[name].member, label,
                                  dtypes=[LAYER_BY_NAME[name].dtype],
                                  ndims=[2 if LAYER_BY_NAME[name].channels is None else 3],
                                  max_bytes=MAX_LAYER_PIXELS * (
                                      LAYER_BY_NAME[name].channels or 1))
            for name in manifest.get("layers", [])
        }
        try:
            grid = IndexGrid(indices, tuple(manifest["cell"]))
            colour_map = _load_colour_map(zf, manifest.get("colour_map"), grid, path,
                                          len(manifest["themes"]))
        except CorruptFileError:
            raise
        except TerrathemeError as exc:
            raise CorruptFileError(f"{path}: {exc}") from None
    try:
        for t, tex in zip(manifest["themes"], textures, strict=True):
            if tex.shape[2] != 3 or max(tex.shape[:2]) > MAX_THEME_SIDE:
                raise TerrathemeError(f"theme {t['name'][:40]!r}: texture of shape {tex.shape} "
                                      f"is not (h, w, 3) with sides up to {MAX_THEME_SIDE}")
        library = ThemeLibrary(
            Theme(t["name"], tuple(t["colour"]), tex, source=t.get("source", ""))
            for t, tex in zip(manifest["themes"], textures, strict=True))
        return ThematicTexture(grid, library, manifest.get("metadata", {}), **layers,
                               colour_map=colour_map)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{path}: {exc}") from None

