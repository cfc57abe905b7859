"""The CLI's rough edges: one line and status 2 for every user error, checks before work."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import terratheme.app.commands.convert
import terratheme.app.commands.themes
import tifffile
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import read_labels, write_image

REPO = Path(__file__).resolve().parents[1]


def _one_error_line(capsys, start: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(start) and "Traceback" not in err, err
    return err


@pytest.mark.parametrize(("exc", "status", "text"), [
    (OSError(28, "No space left on device", "/data/out.png"), 2,
     "terratheme themes: error: /data/out.png: No space left on device"),
    (PermissionError(13, "Permission denied"), 2, "terratheme themes: error: Permission denied"),
    (MemoryError(), 2, "terratheme themes: error: not enough memory for this input"),
    (TerrathemeError("first line\nsecond line"), 2, "terratheme themes: error: first line; "
                                                    "second line"),
    (KeyboardInterrupt(), 130, "terratheme themes: interrupted"),
])
def test_user_errors_are_one_line(monkeypatch, capsys, exc, status, text):
    def fail(args):
        raise exc

    monkeypatch.setattr(terratheme.app.commands.themes, "run", fail)
    assert main(["themes"]) == status
    assert _one_error_line(capsys, "terratheme themes").strip() == text


@pytest.mark.parametrize(("argv", "hint"), [
    (["convert", "photo.jpg", "p.ttproj"], True),
    (["convert", "photo.jpg", "p.ttproj", "--tile", "512"], False),
])
def test_out_of_memory_names_the_bounded_memory_path(monkeypatch, capsys, argv, hint):
    def fail(args):
        raise MemoryError

    monkeypatch.setattr(terratheme.app.commands.convert, "run", fail)
    assert main(argv) == 2
    line = _one_error_line(capsys, "terratheme convert: error: not enough memory for this input")
    assert ("--tile N works in bounded memory" in line) is hint


def test_a_closed_pipe_is_not_a_traceback():
    # A command printing more than a pipe holds, read by "head -c 10".
    code = ("import sys, terratheme.app.commands.themes as t; "
            "t.run = lambda a: [print('x' * 1000) for _ in range(2000)] and 0; "
            "from terratheme.app.cli import main; sys.exit(main(['themes']))")
    proc = subprocess.run(f"{sys.executable} -c \"{code}\" | head -c 10", shell=True, cwd=REPO,
                          env=dict(os.environ, PYTHONPATH=str(REPO)), capture_output=True,
                          text=True, timeout=60)
    assert proc.stdout == "x" * 10
    assert proc.stderr == "", proc.stderr


def test_themes_lists_names_files_colours_and_sizes(capsys):
    assert main(["themes"]) == 0
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if ln.startswith("crop field"))
    assert "crop_field.png" in line and "#e6d23c (230,210,60)" in line and "256 x 256" in line
    assert main(["themes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {"name": "crop field", "file": "crop_field.png"}.items() <= next(
        r for r in rows if r["name"] == "crop field").items()


def test_new_refuses_a_huge_cell_with_the_limit(tmp_path, capsys):
    write_image(tmp_path / "i.png", np.zeros((3, 3), np.uint8))
    assert main(["new", str(tmp_path / "i.png"), str(tmp_path / "p.ttproj"), "--themes", "sand",
                 "--cell", "1000000000"]) == 2
    err = _one_error_line(capsys, "terratheme new: error:")
    assert "over the limit of 4096 texels per side" in err
    assert not (tmp_path / "p.ttproj").exists()


@pytest.fixture()
def photo(tmp_path):
    img = np.zeros((32, 48, 3), np.uint8)
    img[:, 24:] = (200, 180, 120)
    write_image(tmp_path / "photo.png", img)
    return tmp_path


@pytest.mark.parametrize(("extra", "match"), [
    (["--confidence", "{d}/file.txt/c.png"], "cannot make the folder"),
    (["--model-out", "{d}/file.txt/m.ttc", "--scribbles", "{d}/photo.png"],
     "cannot make the folder"),
    (["--confidence", "{d}/photo.png"], "is also an input"),
    (["--confidence", "{d}/labels.png"], "two outputs would be written to the same file"),
])
def test_classify_checks_every_output_before_working(photo, capsys, extra, match):
    (photo / "file.txt").write_text("a file, not a folder")
    args = [a.format(d=photo) for a in extra]
    assert main(["classify", str(photo / "photo.png"), "-o", str(photo / "labels.png"),
                 *args]) == 2
    assert match in _one_error_line(capsys, "terratheme classify: error:")
    assert not (photo / "labels.png").exists()


def test_classify_refuses_writing_over_its_photo(photo, capsys):
    assert main(["classify", str(photo / "photo.png"), "-o", str(photo / "photo.png")]) == 2
    assert "is also an input" in _one_error_line(capsys, "terratheme classify: error:")


def test_classify_with_a_crafted_model_is_one_line(photo, capsys, tmp_path):
    from test_hostile_harness import ZipMember, craft_zip

    meta = {"format": "terratheme-classifier", "version": 2, "classes": [1, 2],
            "options": {"features": {"scale": 10**9}}}
    (tmp_path / "bad.ttc").write_bytes(craft_zip([ZipMember.of("meta.json",
                                                               json.dumps(meta).encode())]))
    assert main(["classify", str(photo / "photo.png"), "-o", str(photo / "l.png"),
                 "--model", str(tmp_path / "bad.ttc")]) == 2
    assert "bad.ttc: damaged classifier metadata (options.features.scale" in _one_error_line(
        capsys, "terratheme classify: error:")


def test_classify_of_an_rgb_plus_infrared_tiff_has_no_no_data_class(tmp_path, capsys):
    data = np.zeros((32, 48, 4), np.uint8)
    data[:, :24, :3] = (40, 90, 200)
    data[:, 24:, :3] = (200, 180, 120)
    data[:, :24, 3] = 0  # water: dark in the near infrared
    data[:, 24:, 3] = 200
    tifffile.imwrite(tmp_path / "nir.tif", data, photometric="rgb", extrasamples=[0])
    assert main(["classify", str(tmp_path / "nir.tif"), "-o", str(tmp_path / "l.png")]) == 0
    labels = read_labels(tmp_path / "l.png")
    assert set(np.unique(labels)) == {1, 2}
    assert "0:" not in capsys.readouterr().out


def test_a_hostile_project_through_the_real_cli_is_one_line(tmp_path):
    from test_hostile_harness import ZipMember, craft_zip

    manifest = {"format": "terratheme-project", "version": 1, "cell": "sixteen",
                "grid_shape": [2, 2], "themes": []}
    (tmp_path / "bad.ttproj").write_bytes(craft_zip([ZipMember.of(
        "manifest.json", json.dumps(manifest).encode())]))
    proc = subprocess.run([sys.executable, "-m", "terratheme.app.cli", "render",
                           str(tmp_path / "bad.ttproj"),
                           str(tmp_path / "out.png")], cwd=REPO, capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=str(REPO)), timeout=120)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "bad.ttproj: cell size must be two whole numbers (N, M), got 'sixteen'" in proc.stderr
