"""How each shipped theme's class looks in real aerial photos: exemplars for naming.

``looks.json`` in the theme folder (written by ``themes/make_looks.py`` from Dubai
photos with ground truth) lists the :class:`~core.themes.matching.Appearance` of each
class under its shipped theme's name; :func:`~core.themes.matching.shipped_names`
uses them beside the textures::

    {"version": 1, "source": "...",
     "looks": [{"name": "water", "lab": [L, a, b], "energy": e, "photo": "..."}, ...]}
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
from terratheme.core.errors import CorruptFileError
from terratheme.core.themes.library import SHIPPED_THEMES_DIR
from terratheme.core.themes.matching import Appearance

LOOKS_FILE = "looks.json"
#: a looks file larger than this is not one
MAX_LOOKS_BYTES = 1 << 20


def read_looks(folder: str | os.PathLike = SHIPPED_THEMES_DIR) -> list[tuple[str, Appearance]]:
    """The ``(theme name, appearance)`` exemplars of ``folder/looks.json`` (none without one).

    Raises :class:`CorruptFileError` for a file not in the module docstring's form, or too large.
    """
    path = Path(folder) / LOOKS_FILE
    if not path.is_file():
        return []
    try:
        if path.stat().st_size > MAX_LOOKS_BYTES:
            raise ValueError(f"larger than {MAX_LOOKS_BYTES} bytes")
        entries = json.loads(path.read_text(encoding="utf-8"))["looks"]
        out = []
        for entry in entries:
            name, lab, energy = str(entry["name"]), entry["lab"], float(entry["energy"])
            lab = [float(v) for v in lab]
            if len(lab) != 3 or not all(map(math.isfinite, [*lab, energy])) or energy < 0:
                raise ValueError(f"look of {name!r}: lab must be 3 finite numbers, energy >= 0")
            out.append((name, Appearance(np.asarray(lab), energy)))
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        raise CorruptFileError(f"{path}: not a looks file ({str(exc)[:80]})") from None
    return out
