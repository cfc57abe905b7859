"""One rule for output folders: every command makes the missing folders of its outputs.

``convert`` always did; the other commands refused a missing folder. A user
naming ``out/run1/x.png`` expects the file there, as ``mkdir -p`` would.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from terratheme.app.cli import main
from terratheme.core.io.images import write_image

SAMPLES = Path(__file__).resolve().parents[1] / "sample_maps"


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("p") / "made" / "here" / "coast.ttproj"
    assert main(["new", str(SAMPLES / "coastline.png"), str(out), "--themes",
                 "water,sand,grass,forest,town,road", "--cell", "4"]) == 0
    assert out.is_file()
    return out


@pytest.mark.parametrize("argv", [
    ["render", "{p}", "{o}/a/b/r.png", "--scale", "0.5"],
    ["export", "{p}", "{o}/a/b/unity", "--engine", "unity", "--size", "64x64"],
    ["pack", str(SAMPLES / "coastline.png"), "{o}/a/b/p.ttpack"],
])
def test_each_command_makes_its_output_folders(project, tmp_path, argv, capsys):
    args = [a.format(p=project, o=tmp_path) for a in argv]
    assert main(args) == 0, capsys.readouterr().err
    assert Path(args[2]).exists()


def test_unpack_and_classify_make_their_output_folders(project, tmp_path, capsys):
    packed = tmp_path / "p.ttpack"
    assert main(["pack", str(SAMPLES / "coastline.png"), str(packed)]) == 0
    assert main(["unpack", str(packed), str(tmp_path / "u" / "v" / "grid.png")]) == 0
    photo = tmp_path / "photo.png"
    rgb = np.zeros((48, 64, 3), np.uint8)
    rgb[:, 32:] = (40, 90, 200)
    write_image(photo, rgb)
    assert main(["classify", str(photo), "-o", str(tmp_path / "c" / "d" / "labels.png"),
                 "--themes", "2"]) == 0, capsys.readouterr().err
    assert (tmp_path / "u/v/grid.png").is_file() and (tmp_path / "c/d/labels.png").is_file()
