"""``--model aerial``: the shipped classifier in convert and classify, themes named by class."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.classify import shipped_models
from terratheme.core.io.images import read_image, read_labels, write_image
from terratheme.core.model.project import load_project

SAMPLE = Path(__file__).resolve().parents[1] / "sample_maps" / "dubai_marina.jpg"

pytestmark = pytest.mark.skipif("aerial" not in shipped_models(),
                                reason="the shipped aerial model is not in models/")


@pytest.fixture(scope="module")
def crop(tmp_path_factory) -> Path:
    """A 256 x 192 piece of the bundled photo: water, land, road and buildings."""
    photo = read_image(SAMPLE)
    path = tmp_path_factory.mktemp("aerial") / "crop.png"
    write_image(path, np.ascontiguousarray(photo[60:252, 600:856, :3]))
    return path


def assert_named_after_the_classes(names):
    """The classes' themes are named after the model's classes, their calm twins
    (core.themes.calm) after those."""
    names = set(names) - {"no data"}
    classes = {n for n in names if not n.endswith(" calm")}
    assert classes and classes <= set(shipped_models()["aerial"].class_names.values())
    assert {n.removesuffix(" calm") for n in names} <= classes


def test_convert_names_the_themes_after_the_models_classes(crop, tmp_path, capsys):
    project = tmp_path / "aerial.ttproj"
    assert main(["convert", str(crop), str(project), "--model", "aerial", "--cell", "16"]) == 0
    assert_named_after_the_classes(load_project(project).library.names)
    assert "class " not in capsys.readouterr().out


def test_explicit_names_still_win_over_the_models(crop, tmp_path):
    project = tmp_path / "named.ttproj"
    assert main(["convert", str(crop), str(project), "--model", "aerial", "--cell", "16",
                 "--themes", "1=town,2=sand,3=road,4=grass,5=water"]) == 0
    names = set(load_project(project).library.names) - {"no data"}
    assert names <= {"town", "sand", "road", "grass", "water"}


def test_classify_writes_the_models_class_values(crop, tmp_path):
    out = tmp_path / "labels.png"
    assert main(["classify", str(crop), "-o", str(out), "--model", "aerial"]) == 0
    labels = read_labels(out)
    values = set(np.unique(labels).tolist())
    assert values <= set(shipped_models()["aerial"].class_names)
    assert len(values) >= 2


@pytest.mark.parametrize("command", ["convert", "classify"])
def test_an_unknown_model_name_is_one_line_listing_the_shipped_ones(command, crop, tmp_path,
                                                                    capsys):
    out = tmp_path / ("x.ttproj" if command == "convert" else "x.png")
    args = [str(crop), str(out)] if command == "convert" else [str(crop), "-o", str(out)]
    assert main([command, *args, "--model", "arial"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "arial" in err and "aerial" in err
    assert not out.exists()


def test_the_tiled_path_names_the_themes_after_the_models_classes_too(crop, tmp_path):
    project = tmp_path / "tiled.ttproj"
    assert main(["convert", str(crop), str(project), "--model", "aerial", "--cell", "16",
                 "--tile", "128"]) == 0
    assert_named_after_the_classes(load_project(project).library.names)
