"""The whole-photo path's memory check: free memory read, a photo that cannot fit refused."""

import numpy as np
import pytest

import core.convert.memory_check as memory_check
from app.cli import main
from core.convert.memory_check import BYTES_PER_PIXEL, check_fits, meminfo_available
from core.errors import TerrathemeError
from core.io.images import write_image


def test_meminfo_counts_available_memory_and_free_swap():
    text = "MemTotal:  100 kB\nMemFree: 20 kB\nMemAvailable:  50 kB\nSwapFree: 10 kB\n"
    assert meminfo_available(text) == 60 * 1024
    assert meminfo_available("MemAvailable: 7 kB") == 7 * 1024


@pytest.mark.parametrize("text", ["", "MemTotal: 100 kB", "MemAvailable: lots", "garbage"])
def test_meminfo_without_available_memory_is_unknown(text):
    assert meminfo_available(text) is None


def test_a_photo_is_refused_only_past_the_free_memory():
    need = 30 * 20 * BYTES_PER_PIXEL
    check_fits("p.png", 30, 20, available=need)
    with pytest.raises(TerrathemeError, match=r"p\.png: 30 x 20 pixels need .*\(--tile 2048\)"):
        check_fits("p.png", 30, 20, available=need - 1)


def test_available_memory_is_positive_or_unknown():
    free = memory_check.available_memory()
    assert free is None or free >= 0


def test_convert_refuses_a_photo_that_cannot_fit_before_reading_it(tmp_path, monkeypatch, capfd):
    write_image(tmp_path / "photo.png", np.full((32, 32, 3), 120, np.uint8))
    monkeypatch.setattr(memory_check, "available_memory", lambda: 32 * 32 * BYTES_PER_PIXEL - 1)
    assert main(["convert", str(tmp_path / "photo.png"), str(tmp_path / "p.ttproj")]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "photo.png: 32 x 32 pixels need" in err, err
    assert "--tile 2048" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png"]
