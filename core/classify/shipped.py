"""Classifiers shipped with terratheme (``--model aerial``), found by name in
``models/models.json`` (layout: docs/formats.md, shipped classifiers). ``classes`` names
each class value, which ``convert`` gives the themes; a ``.onnx`` file is a network.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from pathlib import Path

from terratheme.core.classify.network import NetworkClassifier
from terratheme.core.classify.supervised import Classifier
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.archive import parse_json, read_bounded
from terratheme.core.io.inputs import check_input_file

SHIPPED_MODELS_DIR = Path(__file__).resolve().parents[2] / "models"
MODELS_INDEX = "models.json"
#: an index larger than this is not an index
MAX_INDEX_BYTES = 1 << 20
#: a shipped model larger than this is not one (the classifier reader's own ceilings
#: are checked again when it loads)
MAX_MODEL_BYTES = 1 << 30
_NAME = re.compile(r"[A-Za-z0-9_.\- ]{1,64}")
_SHA256 = re.compile(r"[0-9a-fA-F]{64}")


@dataclass(frozen=True)
class ShippedModel:
    """One entry of ``models.json``; ``size`` (bytes) and ``sha256`` as the index says,
    ``scale`` and ``multiple`` a network's input (the photo resized by ``scale``, sides
    multiples of ``multiple``)."""

    name: str
    path: Path
    class_names: dict[int, str]
    description: str = ""
    size: int | None = None
    sha256: str | None = None
    scale: float = 1.0
    multiple: int = 1


def _index_entry(name: object, entry: object, folder: Path) -> ShippedModel:
    """One checked entry of the index (ValueError naming what is wrong)."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(f"model name {repr(name)[:40]} is not 1..64 letters, digits, "
                         "' ', '_', '.' or '-'")
    if not isinstance(entry, dict):
        raise ValueError(f"model {name!r} must be an object")
    file = entry.get("file")
    # A plain file name in the models folder: no folders, no way out of it.
    if (not isinstance(file, str) or not file.strip() or Path(file).name != file
            or file in (".", "..") or not file.isprintable()):
        raise ValueError(f"model {name!r}: file must be a file name in the models folder, "
                         f"not {repr(file)[:60]}")
    classes = entry.get("classes")
    if not isinstance(classes, dict) or not 1 <= len(classes) <= 256:
        raise ValueError(f"model {name!r}: classes must be an object of 1..256 names")
    names = {}
    for key, value in classes.items():
        if not (key.isascii() and key.isdigit() and len(key) <= 3 and int(key) <= 255):
            raise ValueError(f"model {name!r}: class value {key[:20]!r} is not 0..255")
        if not isinstance(value, str) or not value.strip() or not value.isprintable():
            raise ValueError(f"model {name!r}: class {key} needs a name, not "
                             f"{repr(value)[:40]}")
        names[int(key)] = value
    fields = {"description": (str, "string"), "trained_on": (str, "string"),
              "sha256": (str, "string"), "bytes": (int, "whole number")}
    for key, (kind, what) in fields.items():
        value = entry.get(key, kind())
        if not isinstance(value, kind) or isinstance(value, bool):
            raise ValueError(f"model {name!r}: {key} must be a {what}")
    size, digest = entry.get("bytes"), entry.get("sha256")
    if size is not None and not 0 < size <= MAX_MODEL_BYTES:
        raise ValueError(f"model {name!r}: bytes must be 1..{MAX_MODEL_BYTES}")
    if digest is not None and not _SHA256.fullmatch(digest):
        raise ValueError(f"model {name!r}: sha256 must be 64 hexadecimal digits")
    scale, multiple = entry.get("scale", 1.0), entry.get("multiple", 1)
    if not isinstance(scale, (int, float)) or isinstance(scale, bool) or not 0 < scale <= 1:
        raise ValueError(f"model {name!r}: scale must be a number in (0, 1]")
    if not isinstance(multiple, int) or isinstance(multiple, bool) or not 1 <= multiple <= 64:
        raise ValueError(f"model {name!r}: multiple must be a whole number 1..64")
    if not isinstance(entry.get("scores", {}), dict):
        raise ValueError(f"model {name!r}: scores must be an object")
    return ShippedModel(name, folder / file, names, entry.get("description", ""), size, digest,
                        float(scale), multiple)


def shipped_models(folder: str | os.PathLike = SHIPPED_MODELS_DIR) -> dict[str, ShippedModel]:
    """The models listed in ``folder/models.json`` (empty when there is no index).

    Raises CorruptFileError (one line naming the index) when any field is wrong.
    """
    index = Path(folder) / MODELS_INDEX
    if not index.is_file():
        return {}
    data = read_bounded(index, MAX_INDEX_BYTES, f"{index}: not a model index")
    top = parse_json(data, f"{index}: not a model index: its text")
    try:
        if not isinstance(top, dict) or not isinstance(top.get("models"), dict):
            raise ValueError('it must be an object {"models": {name: entry, ...}}')
        return {name: _index_entry(name, entry, Path(folder))
                for name, entry in top["models"].items()}
    except ValueError as exc:
        raise CorruptFileError(f"{index}: not a model index ({exc})") from None


def resolve_model(name_or_path: str | os.PathLike,
                  folder: str | os.PathLike = SHIPPED_MODELS_DIR
                  ) -> tuple[Path, dict[int, str] | None]:
    """The classifier file ``--model`` means, and its class names if it is a shipped one.

    An existing file wins over a shipped model of the same name; neither raises
    TerrathemeError listing the shipped names.
    """
    path = Path(name_or_path)
    if path.is_file():
        return path, None
    models = shipped_models(folder)
    entry = models.get(str(name_or_path))
    if entry is None:
        if os.path.exists(path):  # a folder or a pipe: say what it is
            check_input_file(path, "a model file")
        known = ", ".join(sorted(models)) or "none"
        raise TerrathemeError(f"{name_or_path}: no such model file, nor a shipped model "
                              f"(shipped: {known})")
    if not entry.path.is_file():
        raise TerrathemeError(f"shipped model {entry.name}: {entry.path} is missing")
    _check_shipped_file(entry)
    return entry.path, dict(entry.class_names)


def _check_shipped_file(entry: ShippedModel) -> None:
    """The shipped file is the one the index describes (size, then SHA-256)."""
    size = entry.path.stat().st_size
    if entry.size is not None and size != entry.size:
        hint = " (a Git LFS pointer: run git lfs pull)" if size < 1024 else ""
        raise CorruptFileError(f"shipped model {entry.name}: {entry.path} is {size:,} bytes, "
                               f"the index says {entry.size:,}{hint}")
    if entry.sha256 is not None:
        digest = hashlib.sha256()
        with open(entry.path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
        if digest.hexdigest() != entry.sha256.lower():
            raise CorruptFileError(f"shipped model {entry.name}: {entry.path} is damaged "
                                   "(its SHA-256 is not the index's)")


def load_model(name_or_path: str | os.PathLike,
               folder: str | os.PathLike = SHIPPED_MODELS_DIR
               ) -> Classifier | NetworkClassifier:
    """:meth:`Classifier.load` of :func:`resolve_model`, with a shipped model's class names.

    A shipped ``.onnx`` entry is a :class:`NetworkClassifier` (same interface).
    """
    path, names = resolve_model(name_or_path, folder)
    if names is not None and path.suffix.lower() == ".onnx":
        entry = shipped_models(folder)[str(name_or_path)]
        return NetworkClassifier(path, sorted(names), entry.scale, entry.multiple, names)
    model = Classifier.load(path)
    if names and model.class_names is None:
        model.class_names = {k: names[k] for k in model.classes if k in names}
    return model
