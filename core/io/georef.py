"""GeoTIFF georeference: read it from a photo, write it back onto outputs.

OpenImageIO's wheel exposes no GeoTIFF tags and drops them on write (design.md §9), so
they are read with ``tifffile`` and added to a written TIFF as a new first directory
(old entries plus GeoTIFF ones; pixel data never moves). Other outputs get an ESRI
world file. The georeference is a JSON-ready dict (tag name -> list / str) that travels
in a project's ``metadata["georeference"]``; :func:`validate_georeference` checks it
wherever it is read or used.
"""

from __future__ import annotations

import math
import os
import struct
from pathlib import Path

from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.io.images import image_attributes, image_info

#: GeoTIFF / GDAL tags kept: code -> (name, TIFF type, struct code)
GEO_TAGS = {
    33550: ("ModelPixelScale", 12, "d"),
    33922: ("ModelTiepoint", 12, "d"),
    34264: ("ModelTransformation", 12, "d"),
    34735: ("GeoKeyDirectory", 3, "H"),
    34736: ("GeoDoubleParams", 12, "d"),
    34737: ("GeoAsciiParams", 2, "s"),
    42112: ("GDAL_METADATA", 2, "s"),
    42113: ("GDAL_NODATA", 2, "s"),
}
_NAME_TO_CODE = {v[0]: k for k, v in GEO_TAGS.items()}
#: most entries in a TIFF directory (tifffile refuses more as suspicious)
MAX_IFD_ENTRIES = 4096
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
        if GEO_TAGS[code][2] == "s":
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
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            tags = tif.pages.first.tags
            out = {}
            for code, (name, _, _) in GEO_TAGS.items():
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


def write_georeference(path: str | os.PathLike, georef: dict, *,
                       world_file: str | os.PathLike | None = None) -> list[Path]:
    """Attach ``georef`` to an image file already written; returns the files changed or made.

    TIFF files get the GeoTIFF tags in their first directory; other formats
    get an ESRI world file (:func:`world_file_for`, or at ``world_file`` when
    given: a file set writes it to a temporary first). An empty georeference
    does nothing.
    """
    p = Path(path)
    if not georef:
        return []
    validate_georeference(georef)
    if p.suffix.lower() in _TIFF_SUFFIXES:
        add_tiff_tags(p, georef)
        return [p]
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


def add_tiff_tags(path: str | os.PathLike, georef: dict) -> None:
    """Add the GeoTIFF tags of ``georef`` to the first directory of a TIFF file, in place.

    The new directory goes after the file's end; pointing the header at it is the last
    write (8 bytes at most), so an interrupted call leaves the old directory in force.
    """
    p = Path(path)
    with open(p, "r+b") as fh:
        head = fh.read(16)
        if head[:2] not in (b"II", b"MM"):
            raise TerrathemeError(f"{p}: not a TIFF file")
        bo = "<" if head[:2] == b"II" else ">"
        magic = struct.unpack_from(bo + "H", head, 2)[0]
        if magic == 42:
            big, ptr_fmt, cnt_fmt, entry_size, hdr_ptr = False, "I", "H", 12, 4
        elif magic == 43:
            big, ptr_fmt, cnt_fmt, entry_size, hdr_ptr = True, "Q", "Q", 20, 8
        else:
            raise CorruptFileError(f"{p}: bad TIFF magic number {magic}")
        inline = 8 if big else 4
        ifd = struct.unpack_from(bo + ptr_fmt, head, hdr_ptr)[0]
        # Read the first directory's raw entries (kept verbatim: their offsets stay valid).
        fh.seek(ifd)
        count_bytes = fh.read(struct.calcsize(cnt_fmt))
        if len(count_bytes) != struct.calcsize(cnt_fmt):
            raise CorruptFileError(f"{p}: truncated TIFF directory")
        count = struct.unpack(bo + cnt_fmt, count_bytes)[0]
        if count > MAX_IFD_ENTRIES:
            raise CorruptFileError(f"{p}: TIFF directory of {count:,} entries")
        raw = fh.read(count * entry_size + struct.calcsize(ptr_fmt))
        if len(raw) != count * entry_size + struct.calcsize(ptr_fmt):
            raise CorruptFileError(f"{p}: truncated TIFF directory")
        entries = {
            struct.unpack_from(bo + "H", raw, e * entry_size)[0]:
                raw[e * entry_size : (e + 1) * entry_size]
            for e in range(count)
        }
        next_ifd = struct.unpack_from(bo + ptr_fmt, raw, count * entry_size)[0]
        end = fh.seek(0, os.SEEK_END)
        tail = bytearray(b"\0" if end % 2 else b"")
        base = end
        # Encode every GeoTIFF tag; values too long for the entry go after the file's end.
        for name, value in georef.items():
            code = _NAME_TO_CODE.get(name)
            if code is None:
                continue
            _, ttype, fmt = GEO_TAGS[code]
            if fmt == "s":
                payload = str(value).encode("latin-1") + b"\0"
                n = len(payload)
            else:
                vals = list(value)
                payload = struct.pack(f"{bo}{len(vals)}{fmt}", *vals)
                n = len(vals)
            if len(payload) <= inline:
                field = payload.ljust(inline, b"\0")
            else:
                if len(tail) % 2:
                    tail += b"\0"
                field = struct.pack(bo + ptr_fmt, base + len(tail))
                tail += payload
            entries[code] = struct.pack(bo + "HH" + ptr_fmt, code, ttype, n) + field
        # Append the new directory (word-aligned), then point the header at it.
        if len(tail) % 2:
            tail += b"\0"
        new_ifd = base + len(tail)
        tail += struct.pack(bo + cnt_fmt, len(entries))
        for code in sorted(entries):
            tail += entries[code]
        tail += struct.pack(bo + ptr_fmt, next_ifd)
        if not big and base + len(tail) >= 1 << 32:
            raise TerrathemeError(f"{p}: too large for classic TIFF after adding GeoTIFF tags")
        fh.write(bytes(tail))
        fh.flush()
        fh.seek(hdr_ptr)
        fh.write(struct.pack(bo + ptr_fmt, new_ifd))
