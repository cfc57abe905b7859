"""RenderOptions.threads: the number of worker threads a render uses."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.render import renderer
from terratheme.core.render.renderer import RenderOptions, render_cells, render_labels


def _scene():
    rng = np.random.default_rng(3)
    grid = rng.integers(0, 3, size=(17, 17)).astype(np.uint8)
    themes = [rng.integers(0, 256, size=(20 + 3 * k, 24, 3), dtype=np.uint8) for k in range(3)]
    return grid, themes


def _spy(monkeypatch) -> set[str]:
    """Names of the threads that run render bands."""
    seen: set[str] = set()
    real = renderer._bands

    def bands(h, threads):
        seen.add(f"asked {threads}")
        return real(h, threads)

    monkeypatch.setattr(renderer, "_bands", bands)
    return seen


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_threads_give_the_same_image_and_are_used(threads, monkeypatch):
    grid, themes = _scene()
    seen = _spy(monkeypatch)
    want = render_cells(grid, themes, (16, 16), options=RenderOptions(threads=1))
    got = render_cells(grid, themes, (16, 16), options=RenderOptions(threads=threads))
    np.testing.assert_array_equal(got, want)
    assert f"asked {threads}" in seen
    if threads > 1:
        assert renderer._executor(threads)._max_workers == threads


def test_one_thread_runs_on_the_calling_thread(monkeypatch):
    grid, themes = _scene()
    names: set[str] = set()
    real = renderer.rk.linear_rows

    def spy(*args):
        names.add(threading.current_thread().name)
        return real(*args)

    monkeypatch.setattr(renderer.rk, "linear_rows", spy)
    render_cells(grid, themes, (16, 16), options=RenderOptions(threads=1))
    assert names == {threading.current_thread().name}
    names.clear()
    render_cells(grid, themes, (16, 16), options=RenderOptions(threads=2))
    assert all(n.startswith("terratheme-render") for n in names)


def test_labels_honour_threads():
    grid, _ = _scene()
    one = render_labels(grid, (16, 16), threads=1)
    two = render_labels(grid, (16, 16), threads=2)
    np.testing.assert_array_equal(one, two)


def test_negative_threads_refused():
    grid, themes = _scene()
    with pytest.raises(TerrathemeError, match="threads must be >= 0"):
        render_cells(grid, themes, (16, 16), options=RenderOptions(threads=-1))
