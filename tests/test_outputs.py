"""app.outputs.check_outputs: output paths refused before any work."""

from __future__ import annotations

import os

import pytest
from terratheme.app.outputs import check_outputs
from terratheme.core.errors import TerrathemeError


def test_missing_folders_are_made(tmp_path):
    out = tmp_path / "a" / "b" / "x.png"
    assert check_outputs([out, None]) == [out]
    assert out.parent.is_dir() and not out.exists()


def test_a_folder_is_not_an_output(tmp_path):
    with pytest.raises(TerrathemeError, match="is a folder"):
        check_outputs([tmp_path])


def test_an_input_is_not_an_output(tmp_path):
    src = tmp_path / "in.png"
    src.write_bytes(b"x")
    with pytest.raises(TerrathemeError, match="is also an input"):
        check_outputs([tmp_path / "." / "in.png"], inputs=[src])
    link = tmp_path / "link.png"
    link.symlink_to(src)
    with pytest.raises(TerrathemeError, match="is also an input"):
        check_outputs([link], inputs=[src])


def test_two_outputs_on_one_file(tmp_path):
    with pytest.raises(TerrathemeError, match="same file"):
        check_outputs([tmp_path / "a.png", tmp_path / "b" / ".." / "a.png"])


def test_unwritable_folder(tmp_path, monkeypatch):
    # (root may write anywhere, so the permission answer is what is faked.)
    monkeypatch.setattr(os, "access", lambda path, mode: False)
    with pytest.raises(TerrathemeError, match="not writable"):
        check_outputs([tmp_path / "x.png"])


def test_folder_that_cannot_be_made(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_bytes(b"")
    with pytest.raises(TerrathemeError, match="cannot make the folder"):
        check_outputs([blocker / "sub" / "x.png"])
