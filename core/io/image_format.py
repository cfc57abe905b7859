"""OpenImageIO's side of reading and writing: its error text, and which extensions it writes.

:func:`error_line` reads the pending error of the library, an ``ImageInput``
or an ``ImageOutput`` as one line; a damaged header can put bytes that are
not UTF-8 into that text (an EXR attribute name), which the binding would
raise as ``UnicodeDecodeError``. :func:`check_writable_format` refuses an
output whose extension no writer takes, so a command can say so before it
starts its work rather than after.
"""

from __future__ import annotations

import os
from pathlib import Path

import OpenImageIO as oiio
from terratheme.core.errors import TerrathemeError

#: what the message on an unknown output extension suggests
KNOWN_OUTPUTS = ".png, .tif, .exr, .jpg"


def first_line(text: str) -> str:
    """The first non-blank line of ``text``, stripped ("" if none)."""
    lines = [ln.strip() for ln in text.strip().splitlines() if ln.strip()]
    return lines[0] if lines else ""


def error_line(source: object = oiio) -> str:
    """The first line of the pending OpenImageIO error of ``source`` (the module, an
    ``ImageInput`` or an ``ImageOutput``); "" if there is none."""
    try:
        text = source.geterror()
    except UnicodeDecodeError:
        return "damaged header (its error text is not UTF-8)"
    return first_line(text)


def check_writable_format(path: str | os.PathLike) -> None:
    """Refuse ``path`` as an image output if no OpenImageIO writer takes its extension.

    Raises
    ------
    TerrathemeError
        ``path: no image format is written as '.xyz'`` (or: has no extension).
    """
    out = oiio.ImageOutput.create(str(path))
    if out is not None:
        return
    error_line()  # clear the library's pending error
    suffix = Path(path).suffix
    what = f"no image format is written as {suffix!r}" if suffix else "has no extension"
    raise TerrathemeError(f"{path}: {what}; name the image {KNOWN_OUTPUTS}, ...")
