"""How each shipped theme's class looks in real aerial photos: exemplars for naming.

A shipped theme's own texture is one look of its class; a procedural water
texture is bright blue, while the sea in an orthophoto is near black, so a
class of dark water would be named after the darker "road". ``looks.json``
in the theme folder lists more looks: the :class:`~core.themes.matching.Appearance`
(mean Lab, band-pass energy) of each class of each Dubai photo with a
ground-truth mask, under the shipped theme's name for that class
(building -> town, land -> sand, road -> road, vegetation -> grass, water ->
water), written by ``themes/make_looks.py``::

    {"version": 1, "source": "...",
     "looks": [{"name": "water", "lab": [L, a, b], "energy": e, "photo": "..."}, ...]}

:func:`core.themes.matching.shipped_names` names a class after the theme of
its nearest look, the textures' and these together. Measured by
``make_looks.py --evaluate`` (54 Dubai photos, leave one tile out: a class is
named right when its name is a theme of its majority ground-truth class,
weighted by pixels): 0.49 with the textures alone, 0.70 with the looks.
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

    Raises
    ------
    CorruptFileError
        A file that is not the JSON of the module docstring, or too large.
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
