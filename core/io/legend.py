"""A label mask's legend ``{class value: name}``, read from a JSON or CSV file.

Shapes: ``{"classes": {"1": "Building"}}`` or the bare mapping; ``{"classes":
[{"id": 1, "name": "Building"}]}`` or the bare list (``value``/``class`` name the
number, ``label`` the name); CSV or text lines ``1,Building`` (header and ``#``
lines skipped; quoted fields as RFC 4180, columns after the name not read). Names
become theme names, so each is trimmed, printable and at most :data:`MAX_NAME`
characters; the file is read up to :data:`MAX_LEGEND_BYTES`.
"""

from __future__ import annotations

import csv
import os
import re
from pathlib import Path

from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.archive import parse_json, read_bounded
from terratheme.core.io.inputs import check_input_file

#: largest legend file read
MAX_LEGEND_BYTES = 1 << 20
#: longest class name kept
MAX_NAME = 64
_NUMBER_KEYS = ("id", "value", "class")
_NAME_KEYS = ("name", "label")


def _value(raw: object, label: str) -> int:
    if isinstance(raw, bool):
        raise CorruptFileError(f"{label}: class value {raw!r} is not a whole number 0..255")
    text = str(raw).strip()
    # ASCII digits only: int() also takes other scripts' digits and underscores (1_0).
    if not isinstance(raw, int) and not re.fullmatch(r"[+-]?[0-9]+", text, re.ASCII):
        raise CorruptFileError(
            f"{label}: class value {text[:20]!r} is not a whole number 0..255")
    digits = text.lstrip("+-").lstrip("0") or "0"
    if not isinstance(raw, int) and len(digits) > 3:
        # Past 255 by its length alone (int() refuses numbers of over 4300 digits).
        raise CorruptFileError(f"{label}: class value {text[:20]!r}... is outside 0..255")
    sign = -1 if text.startswith("-") else 1
    value = int(raw) if isinstance(raw, int) else sign * int(digits)
    if not 0 <= value <= 255:
        raise CorruptFileError(f"{label}: class value {value} is outside 0..255")
    return value


def _name(raw: object, label: str, value: int) -> str:
    if not isinstance(raw, str) or not raw.strip():
        raise CorruptFileError(f"{label}: class {value} has no name")
    name = " ".join(raw.split())
    if len(name) > MAX_NAME or not name.isprintable():
        raise CorruptFileError(
            f"{label}: the name of class {value} is not printable text of at most "
            f"{MAX_NAME} characters")
    return name


def _entries_of(data: object, label: str) -> list[tuple[object, object]]:
    """(value, name) pairs of a parsed JSON legend in any of the accepted shapes."""
    if isinstance(data, dict) and "classes" in data:
        data = data["classes"]
    if isinstance(data, dict):
        return list(data.items())
    if isinstance(data, list):
        pairs = []
        for item in data:
            if not isinstance(item, dict):
                raise CorruptFileError(f"{label}: a class entry is not an object with id and name")
            number = next((item[k] for k in _NUMBER_KEYS if k in item), None)
            name = next((item[k] for k in _NAME_KEYS if k in item), None)
            if number is None or name is None:
                raise CorruptFileError(f"{label}: a class entry has no id or no name")
            pairs.append((number, name))
        return pairs
    raise CorruptFileError(f"{label}: not a legend (expected class values and names)")


def _csv_entries(text: str) -> list[tuple[object, object]]:
    """(value, name) of each CSV row ``value,name[,...]`` (quoted as RFC 4180; columns
    after the name, such as a colour, are not read) or text line ``value name``."""
    pairs = []
    for n, line in enumerate(text.splitlines()):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        row = next(csv.reader([line], skipinitialspace=True))
        if len(row) > 1:
            value, name = row[0], row[1]
        else:
            value, _, name = line.partition(" ")
        if n == 0 and not any(ch.isdigit() for ch in value):
            continue  # a header line (words; '١' or '1_0' is a value, refused as such)
        pairs.append((value, name))
    return pairs


def parse_legend(data: bytes, label: str) -> dict[int, str]:
    """The legend in ``data`` (JSON or CSV bytes) as class value -> name.

    ``label`` names the file in errors. Two classes may share a name (their
    themes are numbered, :func:`core.themes.library.distinct_names`).
    """
    data = data.removeprefix(b"\xef\xbb\xbf")  # the byte-order mark some editors write
    text = data.lstrip()
    if text[:1] in (b"{", b"["):
        pairs = _entries_of(parse_json(data, label), label)
    else:
        try:
            pairs = _csv_entries(data.decode("utf-8"))
        except UnicodeDecodeError:
            raise CorruptFileError(f"{label}: not a legend (not UTF-8 text)") from None
    names: dict[int, str] = {}
    for raw_value, raw_name in pairs:
        value = _value(raw_value, label)
        if value in names:
            raise CorruptFileError(f"{label}: class {value} is named twice")
        names[value] = _name(raw_name, label, value)
    if not names:
        raise CorruptFileError(f"{label}: the legend names no class")
    return names


def read_legend(path: str | os.PathLike) -> dict[int, str]:
    """Read a legend file (shapes: see the module docstring) as class value -> name."""
    p = Path(path)
    if not p.exists():
        raise TerrathemeError(f"{p}: no such legend file")
    check_input_file(p, "a legend file")  # a FIFO would block the read
    return parse_legend(read_bounded(p, MAX_LEGEND_BYTES, f"{p}: legend file"), str(p))
