"""Classifiers shipped with terratheme (``--model aerial``), found by name.

The repository's ``models/`` folder holds trained classifier files (written
by :meth:`core.classify.Classifier.save`) and ``models.json``, an index::

    {"models": {"aerial": {"file": "aerial.ttcls",
                           "classes": {"1": "building", "2": "land", ...},
                           "description": "...", "trained_on": "...", "sha256": "..."}}}

``classes`` names each class value of the model (the names ``convert`` gives
the themes of those classes). :func:`resolve_model` turns what a user typed
after ``--model`` into a file: an existing path is that file, a shipped
model's name is its file in ``models/``; :func:`load_model` loads it with its
class names (``Classifier.class_names``). ``models/train_aerial.py`` makes the
``aerial`` model and its index entry.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from core.classify.supervised import Classifier
from core.errors import CorruptFileError, TerrathemeError

SHIPPED_MODELS_DIR = Path(__file__).resolve().parents[2] / "models"
MODELS_INDEX = "models.json"
#: an index larger than this is not an index
MAX_INDEX_BYTES = 1 << 20


@dataclass(frozen=True)
class ShippedModel:
    """One entry of ``models.json``.

    Attributes
    ----------
    name : str
    path : Path
        The classifier file.
    class_names : dict of int -> str
        Name of each class value (theme names for ``convert``).
    description : str
    """

    name: str
    path: Path
    class_names: dict[int, str]
    description: str = ""


def shipped_models(folder: str | os.PathLike = SHIPPED_MODELS_DIR) -> dict[str, ShippedModel]:
    """The models listed in ``folder/models.json`` (empty when there is no index).

    Raises
    ------
    CorruptFileError
        An index that is not the JSON described in the module docstring.
    """
    index = Path(folder) / MODELS_INDEX
    if not index.is_file():
        return {}
    try:
        if index.stat().st_size > MAX_INDEX_BYTES:
            raise ValueError(f"larger than {MAX_INDEX_BYTES} bytes")
        entries = json.loads(index.read_text(encoding="utf-8"))["models"]
        out = {}
        for name, entry in entries.items():
            names = {int(k): str(v) for k, v in entry["classes"].items()}
            if not all(0 <= k <= 255 for k in names) or not str(entry["file"]).strip():
                raise ValueError(f"model {name!r}: class values 0..255 and a file name")
            out[str(name)] = ShippedModel(str(name), Path(folder) / Path(entry["file"]).name,
                                          names, str(entry.get("description", "")))
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise CorruptFileError(f"{index}: not a model index ({exc})") from None
    return out


def resolve_model(name_or_path: str | os.PathLike,
                  folder: str | os.PathLike = SHIPPED_MODELS_DIR
                  ) -> tuple[Path, dict[int, str] | None]:
    """The classifier file ``--model`` means, and its class names if it is a shipped one.

    An existing file wins over a shipped model of the same name.

    Raises
    ------
    TerrathemeError
        Neither a file nor a shipped model's name (the line lists the shipped names).
    """
    path = Path(name_or_path)
    if path.is_file():
        return path, None
    models = shipped_models(folder)
    entry = models.get(str(name_or_path))
    if entry is None:
        known = ", ".join(sorted(models)) or "none"
        raise TerrathemeError(f"{name_or_path}: no such model file, nor a shipped model "
                              f"(shipped: {known})")
    if not entry.path.is_file():
        raise TerrathemeError(f"shipped model {entry.name}: {entry.path} is missing")
    return entry.path, dict(entry.class_names)


def load_model(name_or_path: str | os.PathLike,
               folder: str | os.PathLike = SHIPPED_MODELS_DIR) -> Classifier:
    """:meth:`Classifier.load` of :func:`resolve_model`, with a shipped model's class names.

    Raises
    ------
    TerrathemeError
        As :func:`resolve_model` and :meth:`Classifier.load`.
    """
    path, names = resolve_model(name_or_path, folder)
    model = Classifier.load(path)
    if names and model.class_names is None:
        model.class_names = {k: names[k] for k in model.classes if k in names}
    return model
