"""Input paths that are not regular files: refused by name before they are opened (issue 33).

A named pipe given as an input blocked every reader for good (opening it waits for a writer).
"""

from __future__ import annotations

import os

import pytest
from hostile_fuzz import check_refused, run_cli
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.inputs import check_input_file

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")


@pytest.fixture
def fifo(tmp_path):
    def make(name: str):
        path = tmp_path / name
        os.mkfifo(path)
        return path
    return make


@pytest.mark.parametrize(("name", "argv"), [
    ("in.png", ["convert", "{in}", "{d}/o.ttproj"]),
    ("in.png", ["new", "{in}", "{d}/o.ttproj", "--themes", "water"]),
    ("in.exr", ["new", "{in}", "{d}/o.ttproj", "--themes", "water", "--from", "terrain3d"]),
    ("in.png", ["new", "{in}", "{d}/o.ttproj", "--themes", "water", "--from", "splatmap"]),
    ("in.png", ["pack", "{in}", "{d}/o.ttpack"]),
    ("in.ttpack", ["info", "{in}"]),
    ("in.png", ["perspective", "{in}", "{d}/o.png"]),
    ("in.ttproj", ["perspective", "{in}", "{d}/o.png"]),
    ("in.ttproj", ["render", "{in}", "{d}/o.png"]),
    ("in.ttproj", ["export", "{in}", "{d}/out", "--engine", "unity"]),
])
def test_a_fifo_input_is_one_line_not_a_hang(fifo, tmp_path, name, argv):
    path = fifo(name)
    args = [a.replace("{in}", str(path)).replace("{d}", str(tmp_path)) for a in argv]
    check_refused(run_cli(*args, timeout=60), str(path), "named pipe")


def test_a_fifo_photo_in_the_editor_is_refused(fifo):
    from terratheme.app.editor.launch import load_start_document

    with pytest.raises(TerrathemeError, match="named pipe"):
        load_start_document(str(fifo("photo.png")), classify=False)


def test_only_regular_files_pass(fifo, tmp_path):
    regular = tmp_path / "ok.png"
    regular.write_bytes(b"x")
    assert check_input_file(regular) == regular
    loop = tmp_path / "loop.png"
    loop.symlink_to(loop)
    for path, why in [(fifo("p.png"), "named pipe"), (tmp_path, "is a folder"),
                      (tmp_path / "missing.png", "no such file"), (loop, "symlink loop"),
                      ("/dev/null", "character device")]:
        with pytest.raises(TerrathemeError, match=why):
            check_input_file(path, "an image")
