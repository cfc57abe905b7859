"""Class names from a mask's legend: core.io.legend, the model file, themes and the CLI."""

from __future__ import annotations

import json
import os
import zipfile

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.classify import Classifier, load_model, train_classifier
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.images import write_image
from terratheme.core.io.legend import MAX_LEGEND_BYTES, parse_legend, read_legend
from terratheme.core.model.project import load_project
from terratheme.core.themes import themes_from_photo
from terratheme.core.themes.library import distinct_names


@pytest.mark.parametrize("text", [
    '{"classes": {"1": "Building", "5": "Water"}}',
    '{"1": "Building", "5": "Water"}',
    '{"classes": [{"id": 1, "name": "Building", "rgb": [1, 2, 3]},'
    ' {"id": 5, "name": "Water"}]}',
    '[{"value": 1, "label": "Building"}, {"class": "5", "name": "  Water "}]',
    "value,name\n1,Building\n# a comment\n\n5,Water\n",
    "1 Building\n5 Water",
])
def test_every_legend_shape_reads_the_same(text: str) -> None:
    assert parse_legend(text.encode(), "legend") == {1: "Building", 5: "Water"}


def test_csv_fields_are_quoted_as_rfc_4180_and_later_columns_not_read() -> None:
    """'1,"wa,ter"' kept its quotes and split the name; '1,water,0,0,255' (a colour
    column) named the class 'water,0,0,255'."""
    text = '1,"wa,ter"\n2, "sand ""dry"""\n3,water,0,0,255\n'
    assert parse_legend(text.encode(), "l.csv") == {1: "wa,ter", 2: 'sand "dry"', 3: "water"}


def test_names_are_trimmed_and_may_repeat() -> None:
    names = parse_legend(b'{"2": "Land  (unpaved\\tarea)", "3": "Tree", "4": "tree"}', "l")
    assert names == {2: "Land (unpaved area)", 3: "Tree", 4: "tree"}
    assert distinct_names(names.values()) == ["Land (unpaved area)", "Tree", "tree 2"]
    assert distinct_names(["sand", "sand", "sand 2", "water"]) == [
        "sand", "sand 2", "sand 2 2", "water"]


@pytest.mark.parametrize(("text", "match"), [
    (b'{"classes": 3}', "not a legend"),
    (b'{"300": "x"}', "outside 0..255"),
    (b'{"-1": "x"}', "outside 0..255"),
    (b'{"one": "x"}', "not a whole number"),
    ('{"\u0661": "x"}'.encode(), "not a whole number"),  # ARABIC-INDIC DIGIT ONE
    (b'{"1_0": "x"}', "not a whole number"),
    ("2,y\n\u0661,x\n".encode(), "not a whole number"),
    (b"2,y\n1_0,x\n", "not a whole number"),
    (b'[{"id": true, "name": "x"}]', "not a whole number"),
    (b'[{"id": 1}]', "no id or no name"),
    (b"[1, 2]", "not an object"),
    (b'{"1": ""}', "class 1 has no name"),
    (b'{"1": 7}', "class 1 has no name"),
    (b'{"1": "' + b"x" * 65 + b'"}', "at most 64 characters"),
    (b'{"1": "a\\u0000b"}', "printable"),
    (b"1,a\n1,b\n", "named twice"),
    (b"{}", "names no class"),
    (b'{"1": NaN}', "not valid JSON"),
    (b"\xff\xfe1,a", "not UTF-8"),
])
def test_bad_legends_are_refused(text: bytes, match: str) -> None:
    with pytest.raises(CorruptFileError, match=match):
        parse_legend(text, "legend.json")


def test_read_legend_bounds_the_file(tmp_path) -> None:
    with pytest.raises(TerrathemeError, match="no such legend file"):
        read_legend(tmp_path / "missing.json")
    with pytest.raises(TerrathemeError, match="is a folder, not a legend file"):
        read_legend(tmp_path)
    if hasattr(os, "mkfifo"):  # a named pipe would block the read
        os.mkfifo(tmp_path / "pipe.csv")
        with pytest.raises(TerrathemeError, match="pipe.csv: is a named pipe"):
            read_legend(tmp_path / "pipe.csv")
    big = tmp_path / "big.csv"
    big.write_bytes(b"1," + b"x" * MAX_LEGEND_BYTES)
    with pytest.raises(TerrathemeError, match="legend file: larger than 1048576 bytes"):
        read_legend(big)
    ok = tmp_path / "legend.json"
    ok.write_text(json.dumps({"classes": {"4": "Vegetation"}}))
    assert read_legend(ok) == {4: "Vegetation"}


def _photo() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    img = np.empty((96, 128, 3), np.uint8)
    img[:, :64] = (40, 120, 40)
    img[:, 64:] = (190, 170, 140)
    img = np.clip(img + rng.normal(0, 6, img.shape), 0, 255).astype(np.uint8)
    truth = np.full((96, 128), 2, np.uint8)
    truth[:, 64:] = 7
    return img, truth


def test_themes_take_given_names_and_guess_the_rest() -> None:
    img, truth = _photo()
    # Class 7 is unnamed: it is named by its look, made distinct from the given "sand".
    mapping = themes_from_photo(img, truth, names={2: "sand"})
    assert mapping.library.names[0] == "sand"
    assert mapping.library.names[1] != "sand" and not mapping.library.names[1].startswith(
        "class")
    # A class called "no data" keeps its name; the transparent pixels' theme is numbered.
    truth0 = truth.copy()
    truth0[:4, :4] = 0
    mapping = themes_from_photo(img, truth0, names={2: "No data", 7: "Land"})
    assert mapping.library.names == ["No data", "Land", "no data 2"]


def test_model_file_keeps_class_names(tmp_path) -> None:
    img, truth = _photo()
    model = train_classifier([(img, truth)])
    assert isinstance(model, Classifier)
    assert model.class_names is None
    model.name_classes({2: "Vegetation", 7: "Land", 9: "not a class"})
    assert model.class_names == {2: "Vegetation", 7: "Land"}
    model.save(tmp_path / "m.ttc")
    again = load_model(tmp_path / "m.ttc")
    assert again.class_names == {2: "Vegetation", 7: "Land"}
    # Names stored for a class the model lacks, or unprintable: a damaged file, one line.
    for bad in ({"3": "Road"}, {"2": "a\u0001"}, ["Vegetation"]):
        with zipfile.ZipFile(tmp_path / "m.ttc") as zf:
            members = {n: zf.read(n) for n in zf.namelist()}
        meta = json.loads(members["meta.json"])
        meta["class_names"] = bad
        members["meta.json"] = json.dumps(meta).encode()
        with zipfile.ZipFile(tmp_path / "bad.ttc", "w") as zf:
            for name, data in members.items():
                zf.writestr(name, data)
        with pytest.raises(CorruptFileError, match="damaged classifier metadata"):
            load_model(tmp_path / "bad.ttc")


@pytest.fixture()
def files(tmp_path):
    img, truth = _photo()
    write_image(tmp_path / "photo.png", img)
    write_image(tmp_path / "truth.png", truth)
    scribbles = np.zeros_like(truth)
    scribbles[40:44, 10:40] = 2
    scribbles[40:44, 80:110] = 7
    write_image(tmp_path / "scribbles.png", scribbles)
    (tmp_path / "legend.json").write_text(json.dumps(
        {"classes": [{"id": 2, "name": "Vegetation"}, {"id": 7, "name": "Land"}]}))
    return tmp_path


def test_classify_legend_goes_into_the_model_and_convert_names_themes(files, capsys) -> None:
    d = files
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "l.png"),
                 "--train", str(d / "photo.png"), str(d / "truth.png"),
                 "--legend", str(d / "legend.json"), "--model-out", str(d / "m.ttc")]) == 0
    assert "2 Vegetation:" in capsys.readouterr().out
    assert main(["convert", str(d / "photo.png"), str(d / "a.ttproj"),
                 "--model", str(d / "m.ttc"), "--cell", "8"]) == 0
    assert load_project(d / "a.ttproj").library.names == ["Vegetation", "Land"]
    # convert --scribbles --legend names the themes too.
    assert main(["convert", str(d / "photo.png"), str(d / "b.ttproj"),
                 "--scribbles", str(d / "scribbles.png"), "--legend", str(d / "legend.json"),
                 "--cell", "8"]) == 0
    assert load_project(d / "b.ttproj").library.names == ["Vegetation", "Land"]


@pytest.mark.parametrize(("extra", "match"), [
    ([], "--legend names the classes of --scribbles or --model"),
    (["--scribbles", "SCRIBBLES", "--themes", "water,sand"], "does not go with --themes"),
])
def test_convert_legend_misuse_is_one_line(files, capsys, extra, match) -> None:
    d = files
    extra = [str(d / "scribbles.png") if e == "SCRIBBLES" else e for e in extra]
    assert main(["convert", str(d / "photo.png"), str(d / "c.ttproj"),
                 "--legend", str(d / "legend.json"), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0]
    assert not (d / "c.ttproj").exists()


def test_classify_legend_needs_classes(files, capsys) -> None:
    d = files
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "l.png"),
                 "--legend", str(d / "legend.json")]) == 2
    assert "--legend names the classes" in capsys.readouterr().err
    (d / "bad.json").write_text('{"1": ')
    assert main(["classify", str(d / "photo.png"), "-o", str(d / "l.png"),
                 "--scribbles", str(d / "scribbles.png"), "--legend", str(d / "bad.json")]) == 2
    assert "not valid JSON" in capsys.readouterr().err
    assert not (d / "l.png").exists()
