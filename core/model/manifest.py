"""The project manifest (``manifest.json`` of a ``.ttproj``): its names and its checks.

:func:`check_manifest` type- and range-checks every field a reader relies on
before any member is read (docs/formats.md, Projects), so a damaged or
hostile manifest is one line naming the field; :mod:`core.model.project`
reads and writes the archive around it.
"""

from __future__ import annotations

from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.io.georef import validate_georeference
from terratheme.core.model.grid import MAX_THEMES, validate_cell
from terratheme.core.model.layers import LAYER_BY_NAME

FORMAT_NAME = "terratheme-project"
FORMAT_VERSION = 5
#: the version a project is written in without a tiled colour map (readable by older readers)
BASE_VERSION = 1
#: the version a tiled colour map needs
TILED_MAP_VERSION = 2
#: the version an upsampled colour map needs (docs/formats.md, the colour map)
UPSAMPLED_MAP_VERSION = 3
#: the version a sharpened colour map needs (docs/formats.md, the colour map)
SHARPENED_MAP_VERSION = 4
#: the version a predicted colour map needs (docs/formats.md, the colour map)
PREDICTED_MAP_VERSION = 5
MANIFEST = "manifest.json"
GRID_MEMBER = "grid.npy"
#: longest theme name / source string kept
MAX_TEXT = 4096


def _whole(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _text(value: object, what: str, *, empty: bool = False) -> str:
    if not isinstance(value, str) or (not empty and not value.strip()) or len(value) > MAX_TEXT:
        raise TerrathemeError(f"{what} must be a{'' if empty else ' non-empty'} string of at "
                              f"most {MAX_TEXT} characters, got {_show(value)}")
    return value


def _show(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def check_manifest(manifest: object) -> dict:
    """Type- and range-check every manifest field; returns the manifest."""
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT_NAME:
        raise CorruptFileError("not a terratheme project (wrong format tag)")
    version = manifest.get("version")
    if not _whole(version) or version < 1:
        raise CorruptFileError(f"bad format version {_show(version)}")
    if version > FORMAT_VERSION:
        raise UnsupportedVersionError(
            f"written by a newer terratheme (project format {_show(version)}; "
            f"this version reads up to {FORMAT_VERSION})")
    for key in ("cell", "grid_shape", "themes"):
        if key not in manifest:
            raise TerrathemeError(f"damaged manifest (missing {key!r})")
    validate_cell(manifest["cell"])
    shape = manifest["grid_shape"]
    if not (isinstance(shape, list) and len(shape) == 2 and all(_whole(v) for v in shape)):
        raise TerrathemeError(f"grid_shape must be two whole numbers, got {_show(shape)}")
    themes = manifest["themes"]
    if not isinstance(themes, list) or not 1 <= len(themes) <= MAX_THEMES:
        raise TerrathemeError(f"themes must be a list of 1..{MAX_THEMES} entries")
    textures = set()
    for k, t in enumerate(themes):
        if not isinstance(t, dict):
            raise TerrathemeError(f"theme {k} is not an object")
        _text(t.get("name"), f"theme {k} name")
        _text(t.get("source", ""), f"theme {k} source", empty=True)
        colour = t.get("colour")
        if not (isinstance(colour, list) and len(colour) == 3
                and all(_whole(c) and 0 <= c <= 255 for c in colour)):
            raise TerrathemeError(f"theme {k} colour must be three whole numbers 0..255, "
                                  f"got {_show(colour)}")
        member = _text(t.get("texture"), f"theme {k} texture")
        if member in textures or member == GRID_MEMBER or member == MANIFEST:
            raise TerrathemeError(f"theme {k} texture {member!r} is used twice")
        textures.add(member)
    metadata = manifest.get("metadata", {})
    if not isinstance(metadata, dict):
        raise TerrathemeError(f"metadata must be a JSON object, not {type(metadata).__name__}")
    if "georeference" in metadata:
        validate_georeference(metadata["georeference"])
    layers = manifest.get("layers", [])
    if not isinstance(layers, list) or not all(isinstance(n, str) for n in layers):
        raise TerrathemeError(f"layers must be a list of names, got {_show(layers)}")
    if len(set(layers)) != len(layers):
        raise TerrathemeError(f"a layer is listed twice in {_show(layers)}")
    unknown = [n for n in layers if n not in LAYER_BY_NAME]
    if unknown:
        raise UnsupportedVersionError(
            f"has a layer {unknown[0][:40]!r} this terratheme does not know "
            f"(known: {', '.join(LAYER_BY_NAME)}); written by a newer version?")
    return manifest
