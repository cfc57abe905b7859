"""Shared pytest fixtures.

``shared_data`` points at ../shared/data (real photos and maps) and skips the
test cleanly when the folder is absent, as on a user's checkout.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """../shared, or skip."""
    if not SHARED.is_dir():
        pytest.skip("../shared is absent (user checkout): real-data test skipped")
    return SHARED


def _shared_folder(shared_dir: Path, name: str, kind: str) -> Path:
    """../shared/NAME, or skip the ``kind`` test."""
    folder = shared_dir / name
    if not folder.is_dir():
        pytest.skip(f"../shared/{name} is absent: {kind} test skipped")
    return folder


@pytest.fixture(scope="session")
def shared_data(shared_dir: Path) -> Path:
    """../shared/data, or skip."""
    return _shared_folder(shared_dir, "data", "real-data")


@pytest.fixture(scope="session")
def shared_vectors(shared_dir: Path) -> Path:
    """../shared/vectors, or skip."""
    return _shared_folder(shared_dir, "vectors", "vector")


@pytest.fixture(scope="session")
def block_photo():
    """Factory: a photo of square blocks in three colours with noise.

    ``block_photo(rng, (rows, cols), block, noise)`` returns ``(photo, classes)``:
    ``photo`` (rows*block, cols*block, 3) uint8, ``classes`` the block class
    (0, 1 or 2) of every pixel.
    """
    colours = np.array([(40, 110, 40), (60, 80, 170), (200, 185, 150)], np.uint8)

    def make(rng, grid, block, noise):
        classes = np.kron(rng.integers(0, 3, grid), np.ones((block, block), int))
        photo = colours[classes] + rng.normal(0, noise, classes.shape + (3,))
        return np.clip(photo, 0, 255).astype(np.uint8), classes

    return make


@pytest.fixture(scope="session")
def small_texture():
    """Factory: a small project of theme 0 everywhere, for the editor and document tests.

    ``small_texture(themes=3, seed=5, **layers)`` returns a ThematicTexture of
    9 x 13 vertices and 8 x 8-texel cells over the first ``themes`` of grass,
    water and sand (random 8 x 8 texels drawn from ``seed``); ``layers``
    (``photo``, ``scribbles``, ...) go to ThematicTexture as they are.
    """

    def make(themes: int = 3, seed: int = 5, **layers):
        from terratheme.core.model.grid import IndexGrid
        from terratheme.core.model.project import ThematicTexture
        from terratheme.core.themes.library import Theme, ThemeLibrary

        rng = np.random.default_rng(seed)
        named = (("grass", (90, 160, 60)), ("water", (40, 80, 170)), ("sand", (210, 190, 120)))
        lib = ThemeLibrary(Theme(n, c, rng.integers(0, 256, (8, 8, 3), dtype=np.uint8))
                           for n, c in named[:themes])
        return ThematicTexture(IndexGrid(np.zeros((9, 13), np.uint8), (8, 8)), lib, **layers)

    return make


@pytest.fixture
def open_window(qtbot, monkeypatch):
    """Factory: ``open_window(document)`` shows an editor window on it, offscreen.

    Message boxes do not block: errors are collected in ``window.errors`` and
    "discard changes?" questions answer Discard. Running jobs are waited for
    at teardown.
    """
    windows = []

    def make(document):
        from PySide6.QtWidgets import QMessageBox
        from terratheme.app.editor.window import MainWindow

        errors: list[str] = []
        monkeypatch.setattr(QMessageBox, "critical", lambda *a, **k: errors.append(a[2]))
        monkeypatch.setattr(QMessageBox, "question",
                            lambda *a, **k: QMessageBox.StandardButton.Discard)
        win = MainWindow(document)
        win.errors = errors
        qtbot.addWidget(win)
        win.resize(900, 600)
        win.show()
        qtbot.waitExposed(win)
        win.fit()
        windows.append(win)
        return win

    yield make
    for win in windows:
        win.wait_for_jobs()


@pytest.fixture(scope="session")
def gl_ctx():
    """The shared OpenGL 3.3 context (``core.gpu.gl_context``), or skip with the reason."""
    from terratheme.core.gpu import GpuUnavailableError, gl_context

    try:
        return gl_context()
    except GpuUnavailableError as exc:
        pytest.skip(f"no OpenGL 3.3 context: {exc}")


@pytest.fixture(scope="module")
def gpu_renderer(gl_ctx):
    """Factory: ``gpu_renderer(themes)`` is a GpuRenderer on the shared context.

    The renderers made are released when the test module ends.
    """
    from terratheme.core.gpu import GpuRenderer

    made = []

    def make(themes):
        made.append(GpuRenderer(themes))
        return made[-1]

    yield make
    for renderer in made:
        renderer.release()
