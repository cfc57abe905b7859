"""The project file: a thematic texture (grid + theme library + metadata) in one file.

Format (``.ttproj``, version 1) — a ZIP archive, every member checked by its
CRC-32 on reading:

``manifest.json``
    ``{"format": "terratheme-project", "version": 1, "cell": [N, M],
    "grid_shape": [rows, cols], "themes": [{"name", "colour", "source",
    "texture": "themes/000.npy"}, ...], "metadata": {...},
    "layers": ["photo", "scribbles"]}``
``grid.npy``
    ``(gh+1, gw+1) uint8`` vertex indices (numpy ``.npy``, no pickles).
``themes/KKK.npy``
    ``(h, w, 3) uint8`` texture of theme ``KKK``.
``photo.npy``, ``scribbles.npy`` (optional)
    the source photo ``(H, W, 3) uint8`` and the scribble mask ``(H, W) uint8``.
``colour_map.webp`` (or another codec), or ``colour_map.npy`` (optional)
    the colour gain over the texture (:mod:`core.model.colour_map`) as it
    ships; the manifest's ``"colour_map": {"scale", "codec", "member"}``
    says which (codec null: a raw ``(mh, mw, 3) uint8`` ``.npy``).

``metadata`` is free JSON: ``source_photo`` (path), ``georeference`` (the
photo's GeoTIFF/CRS attributes), ``created_by``. Saving writes a temporary
file and renames it; loading a damaged file raises ``CorruptFileError`` and a
newer version ``UnsupportedVersionError``.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from core.io.atomic import atomic_path
from core.io.codec import CODECS
from core.model.colour_map import ColourMap
from core.model.grid import IndexGrid, validate_indices
from core.themes.library import Theme, ThemeLibrary

FORMAT_NAME = "terratheme-project"
FORMAT_VERSION = 1
PROJECT_SUFFIX = ".ttproj"
_LAYERS = ("photo", "scribbles")


@dataclass(eq=False)
class ThematicTexture:
    """A thematic texture: the index grid, its theme library and metadata.

    Attributes
    ----------
    grid : IndexGrid
    library : ThemeLibrary
        ``library[k]`` is the theme for index ``k``; every grid index must have one.
    metadata : dict
        JSON-serialisable: ``source_photo``, ``georeference``, ...
    photo : (H, W, 3) uint8 ndarray or None
        The source photo, kept for the editor's overlay and fidelity view.
    scribbles : (H, W) uint8 ndarray or None
        User scribbles for supervised classification (0 = unlabelled).
    colour_map : ColourMap or None
        Low-resolution colour gain over the whole texture (every renderer applies it).
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
            and same(self.photo, other.photo)
            and same(self.scribbles, other.scribbles)
            and self.colour_map == other.colour_map
        )


def _npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(arr), allow_pickle=False)
    return buf.getvalue()


def _load_npy(zf: zipfile.ZipFile, member: str, path: Path) -> np.ndarray:
    try:
        with zf.open(member) as fh:
            return np.load(io.BytesIO(fh.read()), allow_pickle=False)
    except KeyError as exc:
        raise CorruptFileError(f"{path}: project lacks {member}") from exc
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise CorruptFileError(f"{path}: {member} is damaged ({exc})") from exc


def _load_colour_map(zf: zipfile.ZipFile, entry: object, grid: IndexGrid,
                     path: Path) -> ColourMap | None:
    """The colour map the manifest names, checked against the grid before decoding."""
    if entry is None:
        return None
    if not isinstance(entry, dict) or not isinstance(entry.get("member"), str):
        raise CorruptFileError(f"{path}: bad colour_map entry in the manifest")
    scale, codec = entry.get("scale"), entry.get("codec")
    if isinstance(scale, bool) or not isinstance(scale, int) or not 1 <= scale <= 4096:
        raise CorruptFileError(f"{path}: colour map scale must be an integer 1..4096")
    shape = ColourMap.shape_for(grid.texture_size, scale)
    if codec is None:
        return ColourMap(_load_npy(zf, entry["member"], path), scale)
    if codec not in CODECS:
        raise CorruptFileError(f"{path}: unknown colour map codec {codec!r}")
    try:
        data = zf.read(entry["member"])
    except KeyError:
        raise CorruptFileError(f"{path}: project lacks {entry['member']}") from None
    return ColourMap.from_bytes(data, codec, scale, shape)


def save_project(path: str | os.PathLike, project: ThematicTexture) -> None:
    """Write ``project`` to ``path`` (a ``.ttproj`` file) atomically."""
    validate_indices(project.grid.indices, n_themes=len(project.library))
    themes = []
    members: dict[str, bytes] = {"grid.npy": _npy_bytes(project.grid.indices)}
    for k, theme in enumerate(project.library):
        member = f"themes/{k:03d}.npy"
        members[member] = _npy_bytes(theme.texture)
        themes.append(
            {"name": theme.name, "colour": list(theme.colour), "source": theme.source,
             "texture": member}
        )
    layers = []
    for name in _LAYERS:
        arr = getattr(project, name)
        if arr is not None:
            members[f"{name}.npy"] = _npy_bytes(arr)
            layers.append(name)
    extra = {}
    cmap = project.colour_map
    if cmap is not None:
        if cmap.data is not None:
            member = "colour_map" + CODECS[cmap.codec][0]
            members[member] = cmap.data
        else:
            member = "colour_map.npy"
            members[member] = _npy_bytes(cmap.pixels)
        extra["colour_map"] = {"scale": cmap.scale, "codec": cmap.codec, "member": member}
    manifest = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "cell": list(project.grid.cell),
        "grid_shape": list(project.grid.indices.shape),
        "themes": themes,
        "metadata": project.metadata,
        "layers": layers,
        **extra,
    }
    try:
        manifest_text = json.dumps(manifest, indent=1)
    except TypeError as exc:
        raise TerrathemeError(f"project metadata is not JSON-serialisable: {exc}") from exc
    with atomic_path(path) as tmp:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=6) as zf:
            zf.writestr("manifest.json", manifest_text)
            for member, data in members.items():
                zf.writestr(member, data)


def load_project(path: str | os.PathLike) -> ThematicTexture:
    """Read a ``.ttproj`` file written by :func:`save_project`.

    Raises
    ------
    TerrathemeError
        Missing file.
    CorruptFileError
        Not a ZIP, a damaged member (CRC mismatch), a missing member, a grid
        index without a theme.
    UnsupportedVersionError
        Written by a newer terratheme.
    """
    path = Path(path)
    if not path.is_file():
        raise TerrathemeError(f"{path}: no such project file")
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise CorruptFileError(f"{path}: not a terratheme project (damaged or not a ZIP)") from exc
    with zf:
        try:
            manifest = json.loads(zf.read("manifest.json"))
        except KeyError as exc:
            raise CorruptFileError(f"{path}: not a terratheme project (no manifest)") from exc
        except (json.JSONDecodeError, zipfile.BadZipFile, OSError, ValueError, zlib.error) as exc:
            raise CorruptFileError(f"{path}: damaged manifest ({exc})") from exc
        if not isinstance(manifest, dict) or manifest.get("format") != FORMAT_NAME:
            raise CorruptFileError(f"{path}: not a terratheme project (wrong format tag)")
        version = manifest.get("version")
        if not isinstance(version, int) or version < 1:
            raise CorruptFileError(f"{path}: bad format version {version!r}")
        if version > FORMAT_VERSION:
            raise UnsupportedVersionError(
                f"{path}: written by a newer terratheme (project format {version}; "
                f"this version reads up to {FORMAT_VERSION})"
            )
        try:
            library = ThemeLibrary(
                Theme(t["name"], tuple(t["colour"]), _load_npy(zf, t["texture"], path),
                      source=t.get("source", ""))
                for t in manifest["themes"]
            )
            indices = _load_npy(zf, "grid.npy", path)
            grid = IndexGrid(indices, tuple(manifest["cell"]))
            layers = {
                name: _load_npy(zf, f"{name}.npy", path)
                for name in manifest.get("layers", [])
                if name in _LAYERS
            }
            colour_map = _load_colour_map(zf, manifest.get("colour_map"), grid, path)
            return ThematicTexture(grid, library, dict(manifest.get("metadata", {})), **layers,
                                   colour_map=colour_map)
        except (KeyError, TypeError) as exc:
            raise CorruptFileError(f"{path}: damaged manifest (missing {exc})") from exc
        except CorruptFileError:
            raise
        except TerrathemeError as exc:
            raise CorruptFileError(f"{path}: {exc}") from exc
