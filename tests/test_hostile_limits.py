"""Limits checked before the work: one line naming the file, exit 2, nothing written."""

from __future__ import annotations

import numpy as np
import pytest
import terratheme.core.exchange.maps_to_grid
import terratheme.core.model.project
from terratheme.app.cli import main
from terratheme.core.io.images import write_image


def _refused(capfd, argv: list, *needles: str) -> None:
    """``terratheme ARGV`` exits 2 with one stderr line holding every needle."""
    assert main([str(a) for a in argv]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err


@pytest.mark.parametrize(("kind", "image"), [
    ("index", np.zeros((20, 20), np.uint8)),
    ("splatmap", np.pad(np.full((20, 20, 1), 255, np.uint8), ((0, 0), (0, 0), (0, 3)))),
])
def test_new_refuses_a_grid_over_the_limit_from_the_header(tmp_path, capfd, monkeypatch, kind,
                                                           image):
    # found: a 1 MB splatmap of 16385^2 pixels was read (3.6 GB) before the vertex limit
    monkeypatch.setattr(terratheme.core.model.project, "MAX_GRID_VERTICES", 399)
    monkeypatch.setattr(terratheme.core.exchange.maps_to_grid, "read_bands", _never_read)
    write_image(tmp_path / "m.png", image)
    _refused(capfd, ["new", tmp_path / "m.png", tmp_path / "o.ttproj", "--themes", "water,sand",
                     "--from", kind], "m.png: 20 x 20 pixels: grid of 400 vertices is over")
    assert not (tmp_path / "o.ttproj").exists()


def _never_read(*args, **kwargs):
    raise AssertionError("the map was read before its size was checked")


def test_a_texture_past_float32_range_is_one_line(tmp_path, capfd):
    # found: the cast to float32 warned on stderr before the error line
    write_image(tmp_path / "big.tif", np.full((16, 16, 3), 1e39, np.float64))
    _refused(capfd, ["perspective", "--no-cache", "--size", "32x24", tmp_path / "big.tif",
                     tmp_path / "o.png"], "big.tif", "out-of-float32-range")
    assert not (tmp_path / "o.png").exists()
