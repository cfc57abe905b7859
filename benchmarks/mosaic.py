"""Photos larger than memory for the benchmarks: mosaics of 512-pixel crops (not a benchmark).

``bench_convert.py`` (part B) and ``bench_scale.py`` both measure tiled
conversion on ``side x side`` photos that exist only as tiled TIFFs; this
module writes them, band by band, from random crops of real photos, so the
photo never sits in memory whole.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from terratheme.core.io.images import image_info, read_image
from terratheme.core.io.tiled_writer import TiledImageWriter

#: side of one crop (pixels); also the height of a band written at once
BLOCK = 512


def crop_sources(folder: Path) -> list[Path]:
    """The ``*.jpg`` photos of ``folder`` (sorted) at least ``BLOCK`` pixels on each side."""
    return [p for p in sorted(folder.glob("*.jpg"))
            if min(image_info(p).width, image_info(p).height) >= BLOCK]


def write_mosaic(path: Path, side: int, photos: list[Path], seed: int = 0,
                 **writer_options) -> None:
    """Write a ``side x side`` RGB tiled TIFF of random ``BLOCK``-pixel crops of ``photos``.

    ``side`` is a multiple of ``BLOCK``; ``writer_options`` go to
    :class:`core.io.tiled_writer.TiledImageWriter` (``compression``,
    ``bigtiff``, ...); the tiles are 256 pixels. The same ``seed`` gives the
    same mosaic.
    """
    rng = np.random.default_rng(seed)
    # One decoded photo at a time: consecutive crops often come from the same one.
    cache: dict[Path, np.ndarray] = {}
    with TiledImageWriter(path, side, side, 3, np.uint8, tile=256, **writer_options) as out:
        for by in range(0, side, BLOCK):
            band = np.empty((BLOCK, side, 3), np.uint8)
            for bx in range(0, side, BLOCK):
                # A random photo, then a random crop of it.
                p = photos[int(rng.integers(len(photos)))]
                if p not in cache:
                    cache.clear()
                    cache[p] = read_image(p, dtype=np.uint8)[..., :3]
                img = cache[p]
                y = int(rng.integers(0, img.shape[0] - BLOCK + 1))
                x = int(rng.integers(0, img.shape[1] - BLOCK + 1))
                band[:, bx : bx + BLOCK] = img[y : y + BLOCK, x : x + BLOCK]
            out.write(0, by, band)
