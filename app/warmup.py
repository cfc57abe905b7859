"""Compile the numba kernels once (``python -m app.warmup``, run by ``setup.sh``).

Every kernel is ``cache=True``: the machine code lands beside the sources, so
after this a first conversion, render, lookup or preview starts as fast as a
second one. Each part runs on a tiny input; nothing is written but the cache.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def _render() -> None:
    from core.render import BlendMode, RenderOptions, render_cells, render_labels

    grid = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 1]], np.uint8)
    themes = [np.full((8, 8, 3), 40 * (k + 1), np.uint8) for k in range(2)]
    for blend in BlendMode:
        render_cells(grid, themes, (4, 4), options=RenderOptions(blend=blend, threads=1))
    render_labels(grid, (4, 4), threads=1)


def _curves_and_packing() -> None:
    from core.packing import PackedLayer, pack

    image = (np.arange(12 * 10).reshape(12, 10) // 7 % 3).astype(np.uint8)
    for curve in ("hilbert", "morton"):
        layer = pack(image, curve=curve)
        layer.lookup(np.array([0, 9]), np.array([0, 11]))
        layer.lookup(3, 4)
        PackedLayer.from_bytes(layer.to_bytes()).unpack()


def _classify() -> None:
    from core.classify import classify_unsupervised, train_classifier

    rng = np.random.default_rng(0)
    photo = rng.integers(0, 255, (64, 64, 3), dtype=np.uint8)
    photo[:, 32:] //= 3
    mask = np.zeros((64, 64), np.uint8)
    mask[10:20, 5:25], mask[40:50, 40:60] = 1, 2
    train_classifier([(photo, mask)]).predict(photo)
    classify_unsupervised(photo)


PARTS = {"render": _render, "packing": _curves_and_packing, "classify": _classify}


def main(argv: list[str] | None = None) -> int:
    """Run every part (or those named); prints one line per part."""
    names = argv if argv else list(PARTS)
    for name in names:
        t0 = time.perf_counter()
        PARTS[name]()
        print(f"warmup: {name} kernels ready ({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
