"""Whole-photo work that cannot fit in free memory: free memory read, the photo refused at once."""

import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import terratheme.core.io.memory as memory
from terratheme.app.cli import main
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import write_image
from terratheme.core.io.memory import (
    CLASSIFY_BYTES_PER_PIXEL,
    CLASSIFY_FOREST_BYTES_PER_PIXEL,
    CLASSIFY_NETWORK_BYTES_PER_PIXEL,
    CONVERT_BYTES_PER_PIXEL,
    check_fits,
)

REPO = Path(__file__).resolve().parents[1]


def test_free_memory_counts_available_memory_and_free_swap(monkeypatch):
    monkeypatch.setattr(memory.psutil, "virtual_memory", lambda: SimpleNamespace(available=50))
    monkeypatch.setattr(memory.psutil, "swap_memory", lambda: SimpleNamespace(free=10))
    monkeypatch.setattr(memory, "_cgroup_free", lambda: None)
    monkeypatch.setattr(memory, "_address_space_free", lambda: None)
    assert memory.available_memory() == 60
    monkeypatch.setattr(memory, "_cgroup_free", lambda: 7)
    assert memory.available_memory() == 7


def test_a_photo_is_refused_only_past_the_free_memory():
    check_fits("p.png", 30, 20, 7, available=30 * 20 * 7)
    with pytest.raises(TerrathemeError, match=r"p\.png: 30 x 20 pixels need .* are free: do X$"):
        check_fits("p.png", 30, 20, 7, remedy="do X", available=30 * 20 * 7 - 1)
    with pytest.raises(TerrathemeError, match=r"are free$"):
        check_fits("p.png", 30, 20, 7, available=0)


def test_available_memory_is_positive_or_unknown():
    free = memory.available_memory()
    assert free is None or free >= 0


@pytest.mark.parametrize(("argv", "per_pixel", "remedy"), [
    (["convert", "{d}/photo.png", "{d}/p.ttproj"], CONVERT_BYTES_PER_PIXEL, "--tile 2048"),
    (["classify", "{d}/photo.png", "-o", "{d}/l.png"], CLASSIFY_BYTES_PER_PIXEL, ""),
    (["classify", "{d}/photo.png", "-o", "{d}/l.png", "--scribbles", "{d}/scribbles.png"],
     CLASSIFY_FOREST_BYTES_PER_PIXEL, ""),
    (["classify", "{d}/photo.png", "-o", "{d}/l.png", "--model", "aerial"],
     CLASSIFY_NETWORK_BYTES_PER_PIXEL, ""),
])
def test_a_photo_that_cannot_fit_is_refused_before_reading(tmp_path, monkeypatch, capfd,
                                                           argv, per_pixel, remedy):
    photo = np.full((32, 32, 3), 120, np.uint8)
    photo[:, 16:] = (30, 90, 40)
    write_image(tmp_path / "photo.png", photo)
    scribbles = np.zeros((32, 32), np.uint8)
    scribbles[10, 2:12], scribbles[10, 20:30] = 1, 2
    write_image(tmp_path / "scribbles.png", scribbles)
    monkeypatch.setattr(memory, "available_memory", lambda: 32 * 32 * per_pixel - 1)
    assert main([a.format(d=tmp_path) for a in argv]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "photo.png: 32 x 32 pixels need" in err, err
    assert remedy in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png", "scribbles.png"]
    # with the memory it needs, the same command runs
    monkeypatch.setattr(memory, "available_memory", lambda: 32 * 32 * per_pixel)
    assert main([a.format(d=tmp_path) for a in argv]) == 0


@pytest.mark.skipif(sys.platform == "win32", reason="no address-space limit on Windows")
def test_the_address_space_limit_bounds_available_memory():
    # as under "ulimit -v 8000000": what is left of 8 GiB once the process is loaded
    code = ("import resource; _, hard = resource.getrlimit(resource.RLIMIT_AS); "
            "resource.setrlimit(resource.RLIMIT_AS, (8 << 30, hard)); "
            "from terratheme.core.io.memory import available_memory; print(available_memory())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=REPO, env=dict(os.environ, PYTHONPATH=str(REPO)), timeout=60)
    assert out.returncode == 0, out.stderr
    assert 0 < int(out.stdout) < 8 << 30
