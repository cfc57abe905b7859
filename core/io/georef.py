"""GeoTIFF georeference: read it from a photo, write it with an output.

OpenImageIO's wheel drops GeoTIFF tags (design.md §9), so tifffile reads them and writes
them (``extratags``); other outputs get an ESRI world file. The georeference is a JSON-ready
dict (tag name -> list / str), checked by :func:`validate_georeference` wherever used.
"""

from __future__ import annotations

import math
import os
import stat
import struct
from pathlib import Path

import numpy as np
import tifffile
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.atomic import atomic_path, file_set, write_bytes_atomic
from terratheme.core.io.images import image_attributes, image_info, write_image

#: GeoTIFF / GDAL tags kept: code -> (name, tifffile type: d double, H short, s text)
GEO_TAGS = {
    33550: ("ModelPixelScale", "d"),
    33922: ("ModelTiepoint", "d"),
    34264: ("ModelTransformation", "d"),
    34735: ("GeoKeyDirectory", "H"),
    34736: ("GeoDoubleParams", "d"),
    34737: ("GeoAsciiParams", "s"),
    42112: ("GDAL_METADATA", "s"),
    42113: ("GDAL_NODATA", "s"),
}
_NAME_TO_CODE = {v[0]: k for k, v in GEO_TAGS.items()}
#: most numbers in one GeoTIFF tag (GeoKeyDirectory: 4 per key, at most 65535 keys)
MAX_TAG_VALUES = 4 * 65536
#: longest text tag (GeoAsciiParams, GDAL_METADATA, GDAL_NODATA)
MAX_TAG_TEXT = 1 << 20
#: numbers each numeric tag must hold: (fixed lengths or None, multiple of, minimum)
_TAG_LENGTHS = {
    "ModelPixelScale": ((2, 3), 1, 2),
    "ModelTiepoint": (None, 6, 6),
    "ModelTransformation": ((16,), 1, 16),
    "GeoKeyDirectory": (None, 4, 4),
    "GeoDoubleParams": (None, 1, 0),
}
_TIFF_SUFFIXES = (".tif", ".tiff")
_PIXEL_IS_POINT_KEY = 1025


def validate_georeference(georef: object) -> dict:
    """Return ``georef`` after checking each GeoTIFF tag it names (others pass unchecked).

    Numeric tags must be lists of finite numbers of the tag's length (:data:`_TAG_LENGTHS`;
    GeoKeyDirectory whole numbers 0..65535), text tags Latin-1 strings; else TerrathemeError.
    """
    if not isinstance(georef, dict):
        raise TerrathemeError(f"georeference must be an object, not {type(georef).__name__}")
    for name, value in georef.items():
        code = _NAME_TO_CODE.get(name)
        if code is None:
            continue
        if GEO_TAGS[code][1] == "s":
            if not isinstance(value, str) or len(value) > MAX_TAG_TEXT:
                raise TerrathemeError(f"georeference {name} must be text of at most "
                                      f"{MAX_TAG_TEXT:,} characters")
            try:
                value.encode("latin-1")
            except UnicodeEncodeError:
                raise TerrathemeError(f"georeference {name} is not Latin-1 text") from None
            continue
        fixed, multiple, least = _TAG_LENGTHS[name]
        if not isinstance(value, list | tuple) or len(value) > MAX_TAG_VALUES:
            raise TerrathemeError(f"georeference {name} must be a list of at most "
                                  f"{MAX_TAG_VALUES:,} numbers")
        n = len(value)
        if (fixed is not None and n not in fixed) or n % multiple or n < least:
            raise TerrathemeError(f"georeference {name} has {n} numbers")
        if name == "GeoKeyDirectory":
            ok = all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 65535
                     for v in value)
        else:
            ok = all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                     for v in value)
        if not ok:
            raise TerrathemeError(f"georeference {name} holds a value that is not a finite "
                                  "number in range")
    return georef


def read_georeference(path: str | os.PathLike) -> dict:
    """The georeference of an image file (``{}`` when it has none): the :data:`GEO_TAGS`
    present by name (``{"ModelPixelScale": [sx, sy, sz], ...}``), plus ``"oiio": {name:
    value}`` for georeference attributes OpenImageIO exposes itself."""
    p = Path(path)
    if not p.is_file():
        raise TerrathemeError(f"{p}: no such file")
    georef: dict = {}
    exposed = {name: _jsonable(value)
               for name, value in image_attributes(p, "geotiff:").items()}
    if exposed:
        georef["oiio"] = exposed
    if image_info(p).format_name == "tiff":
        georef.update(_read_geo_tags(p))
    try:
        return validate_georeference(georef)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{p}: {exc}") from None


def _jsonable(value: object) -> object:
    if isinstance(value, tuple | list):
        return [_jsonable(v) for v in value]
    if isinstance(value, bytes):
        return value.decode("latin-1")
    return value


def _read_geo_tags(path: Path) -> dict:
    try:
        with tifffile.TiffFile(path) as tif:
            tags = tif.pages.first.tags
            out = {}
            for code, (name, _) in GEO_TAGS.items():
                tag = tags.get(code)
                if tag is None:
                    continue
                if tag.count > MAX_TAG_VALUES + MAX_TAG_TEXT:
                    raise CorruptFileError(f"{path}: GeoTIFF tag {name} declares "
                                           f"{tag.count:,} values")
                value = _jsonable(tag.value)
                # One-number tags come back from tifffile as scalars.
                out[name] = [value] if isinstance(value, int | float) else value
            return out
    except CorruptFileError:
        raise
    except (tifffile.TiffFileError, struct.error, ValueError, OverflowError, KeyError,
            IndexError, TypeError, AttributeError, MemoryError, OSError) as exc:
        raise CorruptFileError(f"{path}: damaged TIFF directory "
                               f"({' '.join(str(exc).split())[:100]})") from None


def scale_georeference(georef: dict, sx: float, sy: float, *,
                       offset: tuple[float, float] = (0.0, 0.0)) -> dict:
    """The georeference of a window of an image whose corner is old pixel ``offset`` (x, y),
    resampled so one new pixel covers ``sx x sy`` old ones. The tie point stays on the
    raster's corner (pixel-is-area).
    """
    out = dict(validate_georeference(georef))
    ox, oy = float(offset[0]), float(offset[1])
    if (ox, oy) != (0.0, 0.0):
        if "ModelTransformation" in out:
            t = list(out["ModelTransformation"])
            for r in range(3):
                t[4 * r + 3] += t[4 * r] * ox + t[4 * r + 1] * oy
            out["ModelTransformation"] = t
        if "ModelTiepoint" in out and "ModelPixelScale" in out:
            i, j, k, x, y, z = out["ModelTiepoint"][:6]
            px, py = out["ModelPixelScale"][:2]
            out["ModelTiepoint"] = [0.0, 0.0, k, x + (ox - i) * px, y - (oy - j) * py, z,
                                    *out["ModelTiepoint"][6:]]
    if "ModelPixelScale" in out:
        px = list(out["ModelPixelScale"])
        out["ModelPixelScale"] = [px[0] * sx, px[1] * sy, *px[2:]]
    if "ModelTransformation" in out:
        t = list(out["ModelTransformation"])
        for r in range(4):
            t[4 * r] *= sx
            t[4 * r + 1] *= sy
        out["ModelTransformation"] = t
    return out


def world_file_for(path: str | os.PathLike, georef: dict) -> Path | None:
    """The world file (:func:`world_file_name`) of a georeferenced non-TIFF ``path``, or None."""
    if not georef or world_file_lines(georef) is None:
        return None
    return world_file_name(path)


def world_file_name(path: str | os.PathLike) -> Path | None:
    """``path``'s ESRI world file beside it (``.pgw`` PNG, ``.jgw`` JPEG, else ``.wld``;
    None for a TIFF), whether or not it has a georeference."""
    p = Path(path)
    if p.suffix.lower() in _TIFF_SUFFIXES:
        return None
    return p.with_suffix({".png": ".pgw", ".jpg": ".jgw", ".jpeg": ".jgw"}.get(
        p.suffix.lower(), ".wld"))


def stale_world_file(path: str | os.PathLike, georef: dict) -> Path | None:
    """The world file beside the image ``path`` that writing it anew with ``georef`` leaves
    describing the old image (the new one carries none), or None: to be removed with the
    old image, else GIS places the new image by it. Only a regular file beside an existing
    image is stale; a TIFF has no world file."""
    world = world_file_name(path)
    if world is None or world_file_for(path, georef) is not None or not Path(path).exists():
        return None
    try:
        return world if stat.S_ISREG(world.lstat().st_mode) else None
    except OSError:
        return None


def write_georeferenced(path: str | os.PathLike, image: np.ndarray, georef: dict, *,
                        attributes: dict[str, object] | None = None) -> list[Path]:
    """Write ``image`` atomically with ``georef``; returns the files that carry it.

    A TIFF is written by tifffile with the GeoTIFF tags (deflate, predictor); another
    format by :func:`core.io.images.write_image` (``attributes`` passed on), with an ESRI
    world file beside it (:func:`write_georeference`). An empty georeference adds nothing.
    """
    p = Path(path)
    if not georef or p.suffix.lower() not in _TIFF_SUFFIXES:
        world = world_file_for(p, georef)
        if world is None:
            write_image(p, image, attributes=attributes)
            return []
        # The image and its world file as a set: a world file that cannot be written
        # leaves the old image (and its old world file) in place, not a new image placed
        # by the old one.
        with file_set([world, p]):
            write_image(p, image, attributes=attributes)
            return write_georeference(p, georef)
    tags = tiff_extratags(validate_georeference(georef))
    arr = np.asarray(image)
    if arr.ndim not in (2, 3) or 0 in arr.shape:
        raise TerrathemeError(f"cannot write {p}: image shape {arr.shape} has no pixels")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    channels = 1 if arr.ndim == 2 else arr.shape[2]
    with atomic_path(p) as tmp:
        tifffile.imwrite(tmp, arr, photometric="rgb" if channels in (3, 4) else "minisblack",
                         planarconfig="contig" if channels > 1 else None,
                         extrasamples=("unassalpha",) if channels in (2, 4) else None,
                         compression="zlib", predictor=True, extratags=tags, metadata=None,
                         software="terratheme")
    return [p]


def tiff_extratags(georef: dict) -> list[tuple]:
    """tifffile ``extratags`` for the :data:`GEO_TAGS` of a checked georeference."""
    tags = []
    for code, (name, kind) in sorted(GEO_TAGS.items()):
        if name not in georef:
            continue
        value = georef[name]
        if kind == "s":
            tags.append((code, "s", 0, str(value).encode("latin-1"), True))
        else:
            tags.append((code, kind, len(value), tuple(value), True))
    return tags


def write_georeference(path: str | os.PathLike, georef: dict, *,
                       world_file: str | os.PathLike | None = None) -> list[Path]:
    """Write the ESRI world file of image ``path`` (already written); returns the files made.

    The file goes beside it (:func:`world_file_for`), or at ``world_file`` when given
    (a file set writes it to a temporary first). An empty georeference, or one without a
    placement, writes nothing. A TIFF carries its tags instead (:func:`write_georeferenced`).
    """
    p = Path(path)
    if not georef:
        return []
    validate_georeference(georef)
    if p.suffix.lower() in _TIFF_SUFFIXES:
        raise TerrathemeError(f"{p}: a TIFF's GeoTIFF tags are written with its pixels "
                              "(write_georeferenced)")
    world = world_file_lines(georef)
    if world is None:
        return []
    target = Path(world_file) if world_file is not None else world_file_for(p, georef)
    write_bytes_atomic(target, ("\n".join(f"{v:.12g}" for v in world) + "\n").encode())
    return [target]


def world_file_lines(georef: dict) -> list[float] | None:
    """The six numbers of an ESRI world file (A, D, B, E, C, F: centre of the top-left pixel)."""
    validate_georeference(georef)
    keys = georef.get("GeoKeyDirectory") or []
    point = any(
        keys[i] == _PIXEL_IS_POINT_KEY and keys[i + 3] == 2 for i in range(4, len(keys) - 3, 4)
    )
    half = 0.0 if point else 0.5
    if "ModelTransformation" in georef:
        t = georef["ModelTransformation"]
        a, b, c, d, e, f = t[0], t[1], t[3], t[4], t[5], t[7]
        return [a, d, b, e, c + (a + b) * half, f + (d + e) * half]
    if "ModelPixelScale" in georef and "ModelTiepoint" in georef:
        sx, sy = georef["ModelPixelScale"][:2]
        i, j, _, x, y, _ = georef["ModelTiepoint"][:6]
        x0, y0 = x - i * sx, y + j * sy
        return [sx, 0.0, 0.0, -sy, x0 + sx * half, y0 - sy * half]
    return None
