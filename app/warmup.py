"""Compile the numba kernels once (``python -m terratheme.app.warmup``, run by ``setup.sh``).

Every kernel is ``cache=True``. The default parts are what ``convert``, ``render``,
``export`` and the editor run, compiled in two processes; ``packing`` and
``perspective`` compile at first use unless named. ``--if-changed`` does nothing when
a stamp says the same sources were compiled by the same numba; otherwise the old
caches go first (numba sees edits to a kernel's own file only, not to what it inlines).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

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

    rng = np.random.default_rng(1)
    texture = rng.integers(0, 256, (32, 32, 3), dtype=np.uint8)
    camera, size = Camera(height=8, pitch=20), (16, 12)
    # Every method on 8-bit and on float textures (heights, HDR).
    for tex in (texture, texture.astype(np.float32) / 255):
        for method in Method:
            PreparedTexture(tex, FilterOptions(method=method)).render(camera, size)
    for other in (texture[:, :, :1], np.concatenate([texture, texture[:, :, :1]], axis=2)):
        PreparedTexture(other, FilterOptions()).render(camera, size)
    # The family of a float grid stored in 8 and 16 bits; the footprints alone.
    for dtype in (np.uint8, np.uint16):
        build_family(texture[:16, :16].astype(np.float32), 2, 1, dtype=dtype)


def _editor() -> None:
    from terratheme.core.perspective import Camera, FilterOptions, Method, PreparedTexture

    # The Perspective tab's CPU frame (its view without OpenGL): the project's 8-bit render
    # prepared as the tab prepares it, drawn with the tab's first filter.
    texture = np.random.default_rng(1).integers(0, 256, (40, 48, 3), dtype=np.uint8)
    prepared = PreparedTexture(texture, FilterOptions(method=Method.BILINEAR))
    prepared.render(Camera(height=8, pitch=20), (16, 12),
                    FilterOptions(method=Method.PARALLELOGRAM))


def _boundary() -> None:
    from terratheme.core.exchange import shaped_slots
    from terratheme.core.model.colour_map import ColourMap
    from terratheme.core.render import RenderOptions, render_cells, render_overview
    from terratheme.core.render.boundary import BoundaryOptions
    from terratheme.core.render.colour_map import apply_colour_map

    grid = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 1]], np.uint8)
    themes = [np.full((8, 8, 3), 40 * (k + 1), np.uint8) for k in range(2)]
    img = render_cells(grid, themes, (4, 4), options=RenderOptions(boundary=BoundaryOptions()))
    render_overview(grid, themes, (4, 4), scale=0.5, boundary=BoundaryOptions())
    apply_colour_map(img, ColourMap(np.full((1, 1, 3), 128, np.uint8), 8), (0, 0, 8, 8))
    # The exports' weights of the same borders.
    shaped_slots(np.zeros((2, 2), np.uint8), [np.zeros((4, 4, 3), np.uint8)], (2, 2), (3, 3),
                 boundary=BoundaryOptions())


def _convert() -> None:
    from terratheme.core.classify import load_model
    from terratheme.core.convert.photo import convert_photo, write_outputs
    from terratheme.core.errors import TerrathemeError

    # The default conversion and the shipped model's, end to end on a small photo of three
    # regions, written as the command writes them (preview, packed layer, colour map), so the
    # kernels on its way are compiled with the types a real photo gives them.
    rng = np.random.default_rng(2)
    photo = rng.integers(0, 40, (160, 192, 3), dtype=np.uint8)
    photo[:, 64:] += np.array([150, 120, 40], np.uint8)
    photo[80:, 128:] = rng.integers(20, 60, (80, 64, 3), dtype=np.uint8) + np.array(
        [0, 60, 160], np.uint8)
    result = convert_photo(photo)
    with tempfile.TemporaryDirectory() as tmp:
        write_outputs(result.project, Path(tmp, "w.ttproj"),
                      preview_path=Path(tmp, "w_preview.png"), packed_path=Path(tmp, "w.ttpack"))
    try:
        model = load_model("aerial")
    except TerrathemeError:  # a checkout without models/ still warms the rest
        return
    convert_photo(photo, model=model)


PARTS = {"render": _render, "boundary": _boundary, "packing": _curves_and_packing,
         "classify": _classify, "perspective": _perspective, "convert": _convert,
         "editor": _editor}
#: what convert, render, export and the editor run, in two groups of about equal compile
#: time (the shaped borders and the colour map go with convert, which renders them too)
DEFAULT_GROUPS = (("convert", "boundary"), ("render", "classify", "editor"))
STAMP = "terratheme-kernels.stamp"


def kernel_sources_hash(root: Path | None = None) -> str:
    """A hash of the numba-bearing sources under ``root`` (core) and of numba's and Python's
    versions."""
    import numba
    import terratheme.core

    h = hashlib.sha256(f"{numba.__version__} {sys.version}".encode())
    root = root or Path(terratheme.core.__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        text = path.read_bytes()
        if b"numba" in text:
            h.update(str(path.relative_to(root)).encode() + b"\0" + text)
    return h.hexdigest()


def _stamp_path() -> Path | None:
    """Where the stamp lives: beside the caches (in-tree or ``NUMBA_CACHE_DIR``)."""
    import terratheme.core

    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"]) / STAMP
    folder = Path(terratheme.core.__file__).resolve().parent / "__pycache__"
    try:
        folder.mkdir(exist_ok=True)
    except OSError:
        return None
    return folder / STAMP if os.access(folder, os.W_OK) else None


def _drop_in_tree_caches() -> None:
    import terratheme.core

    for path in Path(terratheme.core.__file__).resolve().parent.rglob("__pycache__/*.nb[ic]"):
        path.unlink(missing_ok=True)


def run_parts(names: list[str]) -> int:
    """Run the named parts here, one line each."""
    for name in names:
        t0 = time.perf_counter()
        PARTS[name]()
        print(f"warmup: {name} kernels ready ({time.perf_counter() - t0:.1f} s)", flush=True)
    return 0


def run_groups(groups: list[list[str]]) -> int:
    """The groups side by side (the first here, the others in child processes) on 2+ cores."""
    groups = [g for g in groups if g]
    if len(groups) < 2 or (os.cpu_count() or 1) < 2:
        return run_parts([n for g in groups for n in g])
    children = [subprocess.Popen([sys.executable, "-m", "terratheme.app.warmup", *group])
                for group in groups[1:]]
    try:
        run_parts(groups[0])
    finally:
        codes = [child.wait() for child in children]
    return max(codes)


def main(argv: list[str] | None = None) -> int:
    """Run the named parts (default: :data:`DEFAULT_GROUPS`); ``--if-changed`` as above."""
    args = list(argv or [])
    if_changed = "--if-changed" in args
    names = [a for a in args if a != "--if-changed"]
    unknown = [n for n in names if n not in PARTS]
    if unknown:
        print(f"warmup: unknown part {unknown[0]!r} (parts: {', '.join(PARTS)})",
              file=sys.stderr)
        return 2
    if not if_changed:
        return run_parts(names) if names else run_groups([list(g) for g in DEFAULT_GROUPS])
    stamp, digest = _stamp_path(), kernel_sources_hash()
    done: set[str] = set()
    if stamp is not None:
        lines = stamp.read_text().split() if stamp.is_file() else []
        if lines[:1] == [digest]:
            done = set(lines[1:])
        elif stamp.parent.name == "__pycache__":
            _drop_in_tree_caches()
    todo = [n for n in names or [n for g in DEFAULT_GROUPS for n in g] if n not in done]
    if not todo:
        print("warmup: kernels up to date (nothing to compile)")
        return 0
    groups = [[n for n in g if n in todo] for g in DEFAULT_GROUPS]
    groups[0] += [n for n in todo if all(n not in g for g in DEFAULT_GROUPS)]
    rc = run_groups(groups)
    if rc == 0 and stamp is not None:
        stamp.write_text(" ".join([digest, *sorted(done | set(todo))]) + "\n")
    return rc


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
