"""Compile the numba kernels once (``python -m terratheme.app.warmup``, run by ``setup.sh``).

Every kernel is ``cache=True``: the machine code lands beside the sources, so
after this a first conversion, render, lookup or preview starts as fast as a
second one. Each part runs on a tiny input; nothing is written but the cache.
"""

from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np


def _render() -> None:
    from terratheme.core.render import BlendMode, RenderOptions, render_cells, render_labels

    grid = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 1]], np.uint8)
    themes = [np.full((8, 8, 3), 40 * (k + 1), np.uint8) for k in range(2)]
    for blend in BlendMode:
        render_cells(grid, themes, (4, 4), options=RenderOptions(blend=blend, threads=1))
    render_labels(grid, (4, 4), threads=1)
    # Cells too large for the cached weight tables: each band computes its own rows.
    render_cells(grid[:2, :2], themes, (300, 300), (0, 0, 300, 2),
                 options=RenderOptions(threads=1))


def _curves_and_packing() -> None:
    from terratheme.core.curves import scan_order
    from terratheme.core.packing import PackedLayer, TiledLayer, pack
    from terratheme.core.packing.batch import STRATEGIES, lookup_batch, tiled_words

    image = (np.arange(12 * 10).reshape(12, 10) // 7 % 3).astype(np.uint8)
    bx, by = np.array([0, 9, 4]), np.array([0, 11, 6])
    for curve in ("hilbert", "morton"):
        layer = pack(image, curve=curve)
        layer.lookup(bx[:2], by[:2])
        layer.lookup(3, 4)
        PackedLayer.from_bytes(layer.to_bytes()).unpack()
        # Both batch strategies (the buckets serve tables over 64 MiB), on the layer's
        # read-only `table` view as a caller of lookup_batch passes it, and on a copy.
        for table in (layer.table, layer.table.copy()):
            for strategy in STRATEGIES:
                lookup_batch(bx, by, table, np.empty(3, np.uint8), 2, strategy=strategy)
    # Tiled containers of several tiles, either curve, each payload format, read back from
    # bytes: the joined table and the per-tile path, batched and scalar lookups.
    rng = np.random.default_rng(0)
    big = (rng.integers(0, 3, (5, 6)).repeat(40, 0).repeat(40, 1)).astype(np.uint8)
    xs, ys = rng.integers(0, 240, 4096), rng.integers(0, 200, 4096)
    for curve in ("hilbert", "morton"):
        for fmt in ("compact", "seed", "plane", "streams"):
            data = pack(big, curve=curve, tile_bits=6).to_bytes(format=fmt)
            for join in (True, False):
                tiled = dataclasses.replace(TiledLayer.from_bytes(data), join=join)
                tiled.lookup(xs, ys)
                tiled.lookup(5, 7)
                tiled.unpack()
        # The tiles' tables end to end, looked up by bucket (the strategy of tables over
        # 64 MiB, which a layer this small never picks itself).
        tables = [tiled.tile(i).table for i in range(tiled.tiles_x * tiled.tiles_y)]
        table = np.concatenate(tables)
        starts = np.cumsum([0] + [t.size for t in tables[:-1]])
        words = tiled_words(table, starts, tiled.width, tiled.height, tiled.tile_bits,
                            tiled.tiles_x)
        lookup_batch(xs, ys, table, np.empty(xs.size, np.uint8), 1, words, strategy="buckets")
    # A colour image (runs of packed colours).
    pack(np.array([[0, 40, 80], [200, 10, 10]], np.uint8)[image % 2])
    scan_order(5, 3, "hilbert")


def _classify() -> None:
    from terratheme.core.classify import classify_unsupervised, train_classifier

    rng = np.random.default_rng(0)
    photo = rng.integers(0, 255, (64, 64, 3), dtype=np.uint8)
    photo[:, 32:] //= 3
    mask = np.zeros((64, 64), np.uint8)
    mask[10:20, 5:25], mask[40:50, 40:60] = 1, 2
    train_classifier([(photo, mask)]).predict(photo)
    classify_unsupervised(photo)


def _perspective() -> None:
    from terratheme.core.perspective import Camera, FilterOptions, Method, PreparedTexture
    from terratheme.core.perspective.family import build_family
    from terratheme.core.perspective.footprint import footprint_parameters

    rng = np.random.default_rng(1)
    texture = rng.integers(0, 256, (32, 32, 3), dtype=np.uint8)
    camera, size = Camera(height=8, pitch=20), (16, 12)
    # Every method on 8-bit and on float textures (heights, HDR); the seed's lookup
    # (Lookup.SEED, a benchmark peer) compiles on first use.
    for tex in (texture, texture.astype(np.float32) / 255):
        for method in Method:
            for skew_blend in ((False, True) if method is Method.PARALLELOGRAM else (False,)):
                opts = FilterOptions(method=method, skew_blend=skew_blend)
                PreparedTexture(tex, opts).render(camera, size)
    for other in (texture[:, :, :1], np.concatenate([texture, texture[:, :, :1]], axis=2)):
        PreparedTexture(other, FilterOptions()).render(camera, size)
    # The family of a float grid stored in 8 and 16 bits; the footprints alone.
    for dtype in (np.uint8, np.uint16):
        build_family(texture[:16, :16].astype(np.float32), 2, 1, dtype=dtype)
    footprint_parameters(*np.ones((4, 3)))


def _boundary() -> None:
    from terratheme.core.exchange import shaped_slots
    from terratheme.core.model.colour_map import ColourMap
    from terratheme.core.render import RenderOptions, render_cells, render_overview
    from terratheme.core.render.boundary import BoundaryOptions, noise_field
    from terratheme.core.render.colour_map import apply_colour_map

    grid = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 1]], np.uint8)
    themes = [np.full((8, 8, 3), 40 * (k + 1), np.uint8) for k in range(2)]
    img = render_cells(grid, themes, (4, 4), options=RenderOptions(boundary=BoundaryOptions()))
    noise_field(0, 0, 4, 4, 1, 8)
    render_overview(grid, themes, (4, 4), scale=0.5, boundary=BoundaryOptions())
    apply_colour_map(img, ColourMap(np.full((1, 1, 3), 128, np.uint8), 8), (0, 0, 8, 8))
    # The exports' weights of the same borders.
    shaped_slots(np.zeros((2, 2), np.uint8), [np.zeros((4, 4, 3), np.uint8)], (2, 2), (3, 3),
                 boundary=BoundaryOptions())


def _convert() -> None:
    from terratheme.core.convert.photo import convert_photo

    # The default conversion end to end on a small photo of three regions, so the kernels
    # on its way (the themes' class sums over uint8 colours and float32 statistics, the
    # classification's arg-max) are compiled with the types a real photo gives them.
    rng = np.random.default_rng(2)
    photo = rng.integers(0, 40, (160, 192, 3), dtype=np.uint8)
    photo[:, 64:] += np.array([150, 120, 40], np.uint8)
    photo[80:, 128:] = rng.integers(20, 60, (80, 64, 3), dtype=np.uint8) + np.array(
        [0, 60, 160], np.uint8)
    convert_photo(photo)


PARTS = {"render": _render, "boundary": _boundary, "packing": _curves_and_packing,
         "classify": _classify, "perspective": _perspective, "convert": _convert}


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
