"""Aerial looks of the shipped themes' classes (core.themes.looks) and naming by them."""

from __future__ import annotations

import json

import numpy as np
import pytest
from terratheme.core.errors import CorruptFileError
from terratheme.core.themes import read_looks, shipped_theme_library
from terratheme.core.themes.library import ThemeLibrary, flat_theme
from terratheme.core.themes.matching import Appearance, shipped_names


def _library() -> ThemeLibrary:
    # Flat textures: Lab of pure blue and of dark grey, energy 0.
    return ThemeLibrary([flat_theme("water", (40, 90, 200)), flat_theme("road", (60, 60, 60))])


def test_a_dark_class_is_named_after_its_nearest_look_not_the_nearest_texture():
    dark = Appearance(np.array([8.0, -2.0, 3.0]), 0.0)  # near-black sea
    assert shipped_names([dark], _library()) == ["road"]
    looks = [("water", Appearance(np.array([7.0, -1.0, 2.0]), 0.0))]
    assert shipped_names([dark], _library(), looks) == ["water"]
    # A look of a name the library does not have is skipped.
    assert shipped_names([dark], _library(), [("lake", looks[0][1])]) == ["road"]


def test_repeated_names_are_numbered_with_looks_too():
    dark = Appearance(np.array([8.0, 0.0, 0.0]), 0.0)
    looks = [("water", Appearance(np.array([8.0, 0.0, 0.0]), 0.0))]
    assert shipped_names([dark, dark], _library(), looks) == ["water", "water 2"]


def test_read_looks_round_trip(tmp_path):
    doc = {"version": 1, "looks": [{"name": "water", "lab": [7, -1, 2], "energy": 0.001,
                                    "photo": "x.jpg"}]}
    (tmp_path / "looks.json").write_text(json.dumps(doc))
    [(name, look)] = read_looks(tmp_path)
    assert name == "water" and look.lab.tolist() == [7.0, -1.0, 2.0] and look.energy == 0.001
    assert read_looks(tmp_path / "absent") == []


@pytest.mark.parametrize("looks, message", [
    ("[]", "not a looks file"),
    ('{"looks": [{"name": "w", "lab": [1, 2], "energy": 0}]}', "3 finite numbers"),
    ('{"looks": [{"name": "w", "lab": [1, 2, NaN], "energy": 0}]}', "3 finite numbers"),
    ('{"looks": [{"name": "w", "lab": [1, 2, 3], "energy": -1}]}', "energy >= 0"),
    ('{"looks": [{"lab": [1, 2, 3], "energy": 0}]}', "not a looks file"),
    ("{not json", "not a looks file"),
])
def test_damaged_looks_files_are_one_line(tmp_path, looks, message):
    (tmp_path / "looks.json").write_text(looks)
    with pytest.raises(CorruptFileError, match=message):
        read_looks(tmp_path)


def test_an_oversized_looks_file_is_refused_before_reading(tmp_path):
    (tmp_path / "looks.json").write_bytes(b" " * ((1 << 20) + 1))
    with pytest.raises(CorruptFileError, match="larger than"):
        read_looks(tmp_path)


def test_the_shipped_looks_name_only_shipped_themes():
    looks = read_looks()
    names = set(shipped_theme_library().names)
    assert looks and {name for name, _ in looks} <= names
