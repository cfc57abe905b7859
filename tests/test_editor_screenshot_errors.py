"""The editor's screenshot command on input it cannot show: one line, exit 2, no screenshot."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")

from terratheme.core.model.project import save_project
from terratheme.core.themes.library import Theme


def two_colour_photo() -> np.ndarray:
    """(64, 96, 3) uint8: green left half, blue right half."""
    photo = np.zeros((64, 96, 3), dtype=np.uint8)
    photo[:, :48] = (30, 140, 40)
    photo[:, 48:] = (40, 60, 200)
    return photo


def test_screenshot_of_a_failed_classification_is_one_line_and_no_file(tmp_path, capsys,
                                                                     monkeypatch):
    # found: the failure opened a modal dialog nobody could close, and the command hung
    from terratheme.app.cli import main
    from terratheme.app.editor import classify_job
    from terratheme.core.io.images import write_image

    def fail(*args, **kwargs):
        raise MemoryError("Unable to allocate 3.02 GiB for an array")

    monkeypatch.setattr(classify_job, "run_classification", fail)
    write_image(tmp_path / "photo.png", two_colour_photo())
    out = tmp_path / "shot.png"
    assert main(["app", str(tmp_path / "photo.png"), "--screenshot", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Classification failed: Unable to allocate" in err, err
    assert not out.exists()


def test_a_project_past_the_preview_limit_is_one_line_naming_it(tmp_path, capsys):
    from terratheme.app.cli import main
    from terratheme.core.model.grid import IndexGrid
    from terratheme.core.model.project import ThematicTexture
    from terratheme.core.themes.library import ThemeLibrary

    library = ThemeLibrary([Theme("a", (10, 20, 30), np.zeros((4, 4, 3), np.uint8))])
    big = tmp_path / "big.ttproj"
    save_project(big, ThematicTexture(IndexGrid(np.zeros((6, 6), np.uint8), (4096, 4096)),
                                      library))
    assert main(["app", str(big), "--screenshot", str(tmp_path / "s.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "big.ttproj: the editor's live preview" in err, err
    assert not (tmp_path / "s.png").exists()
