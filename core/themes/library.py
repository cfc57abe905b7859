"""Themes: small tileable textures with a name and a display colour.

A theme ``T[k]`` is sampled at global output coordinates, wrapping, so a
theme flows unbroken across cells (design.md §1). The shipped library lives
in the repository's ``themes/`` folder: ``themes.json`` names each theme, its
display colour and its texture file.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.io.archive import parse_json, read_bounded
from terratheme.core.io.images import read_image

SHIPPED_THEMES_DIR = Path(__file__).resolve().parents[2] / "themes"
THEMES_METADATA = "themes.json"
#: the newest ``themes.json`` version this build reads
THEMES_VERSION = 1
#: largest ``themes.json`` read
MAX_THEMES_METADATA_BYTES = 1 << 20
#: longest theme name a theme folder may give
MAX_THEME_NAME = 64


def validate_texture(texture: object, *, name: str = "theme") -> np.ndarray:
    """Check a theme texture and return it as a C-contiguous (h, w, 3) uint8 array.

    ``texture``: (h, w, 3|4) uint8, uint16 or float in [0, 1]; alpha is dropped.
    Raises :class:`TerrathemeError` when empty, not an image, or not 3/4 channels.
    """
    arr = np.asarray(texture)
    if arr.ndim != 3 or arr.shape[2] not in (3, 4):
        raise TerrathemeError(
            f"{name}: texture must be (height, width, 3) RGB or RGBA, got shape {arr.shape}"
        )
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise TerrathemeError(f"{name}: texture is empty ({arr.shape[1]} x {arr.shape[0]})")
    arr = arr[:, :, :3]
    if arr.dtype == np.uint16:
        arr = (arr.astype(np.uint32) * 255 + 32767) // 65535
    elif arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)):
            raise TerrathemeError(f"{name}: texture has NaN or infinite values")
        arr = np.clip(np.rint(arr * 255.0), 0, 255)
    elif arr.dtype != np.uint8:
        raise TerrathemeError(f"{name}: texture dtype {arr.dtype} not supported (use uint8)")
    return np.ascontiguousarray(arr, dtype=np.uint8)


def _validate_colour(colour: object, name: str) -> tuple[int, int, int]:
    try:
        r, g, b = (int(c) for c in colour)  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise TerrathemeError(
            f"{name}: display colour must be three integers, got {colour!r}"
        ) from exc
    if not all(0 <= c <= 255 for c in (r, g, b)):
        raise TerrathemeError(f"{name}: display colour {colour!r} is outside 0..255")
    return r, g, b


def distinct_names(names: Iterable[str]) -> list[str]:
    """Theme names made distinct (case-insensitive): a repeat takes a free number ("sand 2")."""
    out: list[str] = []
    taken: set[str] = set()
    for name in names:
        unique, n = name, 2
        while unique.lower() in taken:
            unique, n = f"{name} {n}", n + 1
        taken.add(unique.lower())
        out.append(unique)
    return out


@dataclass(frozen=True, eq=False)
class Theme:
    """One theme: a name, an sRGB display colour and a tileable (h, w, 3) uint8 texture.

    ``source`` says where the texture came from (shipped file, photo patch, ...).
    """
    name: str
    colour: tuple[int, int, int]
    texture: np.ndarray = field(repr=False)
    source: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise TerrathemeError(f"theme name must be a non-empty string, got {self.name!r}")
        if not self.name.isprintable():
            # Names are printed: a control character would drive the user's terminal.
            raise TerrathemeError(f"theme name {self.name[:40]!r} is not one line of "
                                  "printable text")
        object.__setattr__(self, "colour", _validate_colour(self.colour, self.name))
        tex = validate_texture(self.texture, name=self.name)
        if tex.flags.writeable or not tex.flags.owndata:
            # A theme owns a read-only copy: its pixels never change behind its back.
            tex = tex.copy()
            tex.setflags(write=False)
        object.__setattr__(self, "texture", tex)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Theme):
            return NotImplemented
        return (
            self.name == other.name
            and self.colour == other.colour
            and self.source == other.source
            and np.array_equal(self.texture, other.texture)
        )

    def with_(self, **changes: object) -> Theme:
        """A copy with some fields changed (rename, recolour, new texture)."""
        return replace(self, **changes)


class ThemeLibrary(Sequence[Theme]):
    """An ordered list of themes; theme index ``k`` in a grid means ``library[k]``."""

    def __init__(self, themes: Iterable[Theme] = ()) -> None:
        self._themes: list[Theme] = []
        for t in themes:
            self.append(t)

    def __len__(self) -> int:
        return len(self._themes)

    def __getitem__(self, k):  # type: ignore[override]
        if isinstance(k, slice):
            return ThemeLibrary(self._themes[k])
        if not -len(self._themes) <= k < len(self._themes):
            raise TerrathemeError(f"no theme with index {k}; the library has {len(self)} themes")
        return self._themes[k]

    def __iter__(self) -> Iterator[Theme]:
        return iter(self._themes)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ThemeLibrary) and self._themes == other._themes

    def __repr__(self) -> str:
        return f"ThemeLibrary({[t.name for t in self._themes]})"

    @property
    def names(self) -> list[str]:
        return [t.name for t in self._themes]

    @property
    def textures(self) -> list[np.ndarray]:
        """Texture arrays in index order, as ``render_cells`` takes them."""
        return [t.texture for t in self._themes]

    @property
    def colours(self) -> np.ndarray:
        """(K, 3) uint8 display colours in index order."""
        return np.array([t.colour for t in self._themes], dtype=np.uint8).reshape(-1, 3)

    def index_of(self, name: str) -> int:
        """Index of the theme called ``name`` (case-insensitive)."""
        low = name.strip().lower()
        for k, t in enumerate(self._themes):
            if t.name.lower() == low:
                return k
        raise TerrathemeError(f"unknown theme {name!r}; known themes: {', '.join(self.names)}")

    def append(self, theme: Theme) -> int:
        """Add a theme at the end; returns its index."""
        if not isinstance(theme, Theme):
            raise TerrathemeError(f"expected a Theme, got {type(theme).__name__}")
        if len(self._themes) >= 256:
            raise TerrathemeError("a theme library holds at most 256 themes")
        if theme.name.lower() in (n.lower() for n in self.names):
            raise TerrathemeError(f"a theme called {theme.name!r} is already in the library")
        self._themes.append(theme)
        return len(self._themes) - 1

    def remove_last(self) -> Theme:
        """Remove and return the last theme (the inverse of :meth:`append`)."""
        if not self._themes:
            raise TerrathemeError("the theme library is empty")
        return self._themes.pop()

    def replace(self, k: int, theme: Theme) -> None:
        """Put ``theme`` at index ``k`` (rename, recolour or retexture a theme)."""
        old = self[k]
        others = [n.lower() for i, n in enumerate(self.names) if i != k % len(self)]
        if theme.name.lower() in others:
            raise TerrathemeError(f"a theme called {theme.name!r} is already in the library")
        self._themes[self._themes.index(old)] = theme

    def select(self, names: Iterable[str]) -> ThemeLibrary:
        """A new library holding the named themes in the given order."""
        return ThemeLibrary(self[self.index_of(n)] for n in names)


def read_theme_library(folder: str | os.PathLike = SHIPPED_THEMES_DIR) -> ThemeLibrary:
    """Load a theme folder: ``themes.json`` (docs/formats.md, theme folders) and one texture each.

    Raises :class:`TerrathemeError` without ``themes.json``; :class:`CorruptFileError` (one
    line naming the file and entry) for an oversized, non-JSON or ill-typed list or an
    unreadable texture; :class:`UnsupportedVersionError` above ``THEMES_VERSION``.
    """
    folder = Path(folder)
    meta_path = folder / THEMES_METADATA
    if not meta_path.is_file():
        raise TerrathemeError(f"{folder}: no {THEMES_METADATA} (not a theme folder)")
    data = read_bounded(meta_path, MAX_THEMES_METADATA_BYTES, str(meta_path))
    try:
        meta = parse_json(data, "its text")
    except CorruptFileError as exc:
        raise CorruptFileError(f"{meta_path}: not a valid theme list: {exc}") from None
    entries = meta.get("themes") if isinstance(meta, dict) else None
    if not isinstance(entries, list) or not entries:
        raise CorruptFileError(f"{meta_path}: not a valid theme list (expected "
                               '{"version": 1, "themes": [{"name", "colour", "file"}, ...]})')
    version = meta.get("version", THEMES_VERSION)
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise CorruptFileError(f"{meta_path}: bad version {str(version)[:20]!r}")
    if version > THEMES_VERSION:
        raise UnsupportedVersionError(f"{meta_path}: theme list version {version}; this "
                                      f"terratheme reads up to {THEMES_VERSION}")
    lib = ThemeLibrary()
    for k, entry in enumerate(entries):
        where = f"{meta_path}: theme {k}"
        file = _entry_file(entry, where)
        try:
            tex = read_image(folder / file, dtype=np.uint8)
            lib.append(Theme(entry["name"], _entry_colour(entry, where), tex,
                             source=f"{folder.name}/{file}"))
        except CorruptFileError:
            raise
        except TerrathemeError as exc:
            raise CorruptFileError(f"{where}: {exc}") from None
    return lib


def _entry_file(entry: object, where: str) -> str:
    """The checked ``file`` of a ``themes.json`` entry (its name checked too)."""
    if not isinstance(entry, dict):
        raise CorruptFileError(f"{where} is not an object with name, colour and file")
    missing = [key for key in ("name", "colour", "file") if key not in entry]
    if missing:
        raise CorruptFileError(f"{where} lacks {missing[0]!r}")
    name = entry.get("name")
    if not isinstance(name, str) or not name.strip() or len(name) > MAX_THEME_NAME \
            or not name.isprintable():
        raise CorruptFileError(f"{where}: name must be one printable line of 1.."
                               f"{MAX_THEME_NAME} characters, got {str(name)[:40]!r}")
    file = entry.get("file")
    if (not isinstance(file, str) or file in ("", ".", "..") or Path(file).name != file
            or not file.isprintable()):  # a NUL would reach os.stat as a ValueError
        raise CorruptFileError(f"{where}: file must be a file name in the theme folder, "
                               f"not {str(file)[:60]!r}")
    return file


def _entry_colour(entry: dict, where: str) -> tuple[int, int, int]:
    colour = entry.get("colour")
    if not (isinstance(colour, list) and len(colour) == 3 and all(
            isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 255 for c in colour)):
        raise CorruptFileError(f"{where}: colour must be three whole numbers 0..255, got "
                               f"{str(colour)[:40]}")
    return (colour[0], colour[1], colour[2])


def shipped_theme_library() -> ThemeLibrary:
    """The themes bundled with terratheme (the repository's ``themes/`` folder)."""
    return read_theme_library(SHIPPED_THEMES_DIR)


def flat_theme(name: str, colour: Sequence[int], size: int = 8) -> Theme:
    """A single-colour theme (used for label previews and as a fallback texture)."""
    tex = np.broadcast_to(np.asarray(colour, dtype=np.uint8), (size, size, 3)).copy()
    return Theme(name, tuple(colour), tex, source="flat colour")
