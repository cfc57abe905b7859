"""Benchmark of the region path against the whole photo: the same texture, tile by tile?

Run: ``.venv/bin/python benchmarks/bench_region.py [--quick] [--tile 512] [--name region]``

Writes ``benchmarks/results/<name>.json`` and ``<name>.png``.

Photos (tiled TIFFs in a temporary folder):

* ``sample_4x4``: the bundled photo (``sample_maps/dubai_marina.jpg``) repeated
  4 x 4 (4504 x 4232, issue 34's "4500 x 4200 mosaic of the sample");
* ``dubai_mosaic``: a 3072 x 3072 mosaic of random 512-pixel crops of the
  shared Dubai photos (``../shared/data/dubai/images``, when present;
  ``benchmarks/mosaic.py``);
* ``villas_3x3``: the villa photo ``image_part_005t4.jpg`` of those repeated 3 x 3
  (3297 x 2538), whose grid is over its byte share: the byte budget's cell growth is
  decided on the region's sample.

Each photo is converted with ``convert``'s defaults three times, each in a
fresh child process (peak RSS from ``ru_maxrss``; forked from a small server
process): the whole photo (``core.convert.photo.convert_photo``), the whole
photo shifted by 16 pixels (its first 16 rows and columns cropped: the whole path's own
self-consistency) and tile by tile (``core.convert.tiled.convert_file_tiled``,
``--tile``). Reported for the tiled and the shifted run against the whole photo:

* ``agreement``: share of pixels (every 4th row and column) whose nearest
  vertex has the same theme, after matching the two theme sets (the
  assignment of most shared pixels, ``scipy.optimize.linear_sum_assignment``);
  with equal cells this is the vertex agreement;

and for every run, its render against the photo: ``dE8``, ``structure 1/4``
and ``1/8`` and ``detail`` (``core.fidelity.metrics``), the themes, the cell
and the colour map's scale and bytes.

``--quick``: the sample mosaic at 2252 x 2116 (2 x 2) only.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data" / "dubai" / "images"
SAMPLE = REPO / "sample_maps" / "dubai_marina.jpg"
RESULTS = REPO / "benchmarks" / "results"
#: pixels the shifted whole-photo run crops from the top and the left
SHIFT = 16
#: every STEP-th row and column of the label views is compared
STEP = 4


def _convert(kind: str, photo: str, out: str, tile: int) -> dict:
    """One conversion in this (child) process; the project saved to ``out``."""
    from terratheme.core.convert.photo import ConvertOptions, convert_photo
    from terratheme.core.convert.tiled import convert_file_tiled
    from terratheme.core.io.images import Bands, read_image
    from terratheme.core.model.project import save_project

    start = time.perf_counter()
    if kind == "tiled":
        project = convert_file_tiled(photo, None, "auto", tile=tile)
    else:
        rgb = read_image(photo, bands=Bands.PHOTO)
        if kind == "shifted":
            rgb = np.ascontiguousarray(rgb[SHIFT:, SHIFT:])
        project = convert_photo(rgb, ConvertOptions()).project
    seconds = time.perf_counter() - start
    save_project(out, project)
    return {"seconds": round(seconds, 1),
            "peak_rss_mib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)}


def _label_view(indices: np.ndarray, cell: tuple[int, int], h: int, w: int,
                offset: int = 0) -> np.ndarray:
    """Theme of the nearest vertex at every STEP-th pixel of an ``h x w`` area.

    ``offset``: the project's texel 0 is photo pixel ``offset`` (the shifted run).
    """
    n, m = cell
    ys = np.arange(0, h, STEP) - offset
    xs = np.arange(0, w, STEP) - offset
    rows = np.clip(np.rint(ys / m).astype(int), 0, indices.shape[0] - 1)
    cols = np.clip(np.rint(xs / n).astype(int), 0, indices.shape[1] - 1)
    return indices[np.ix_(rows, cols)]


def agreement(a: np.ndarray, b: np.ndarray) -> float:
    """Share of equal labels after matching b's themes to a's (most shared pixels)."""
    from scipy.optimize import linear_sum_assignment

    ka, kb = int(a.max()) + 1, int(b.max()) + 1
    confusion = np.bincount(a.ravel().astype(np.int64) * kb + b.ravel(),
                            minlength=ka * kb).reshape(ka, kb)
    rows, cols = linear_sum_assignment(-confusion)
    return float(confusion[rows, cols].sum() / a.size)


def _scores(project, photo: np.ndarray, offset: int = 0) -> dict:
    from terratheme.core.fidelity.metrics import colour_error, detail_ratio, structure_similarity
    from terratheme.core.render.project import render_project

    h, w = photo.shape[:2]
    shown = render_project(project, region=(0, 0, w - offset, h - offset))
    part = photo[offset:, offset:, :3]
    cmap = project.colour_map
    return {
        "dE8": round(colour_error(shown, part), 3),
        "structure_4": round(structure_similarity(shown, part, 4), 4),
        "structure_8": round(structure_similarity(shown, part, 8), 4),
        "detail": round(detail_ratio(shown, part), 3),
        "themes": list(project.library.names),
        "cell": list(project.grid.cell),
        "colour_map_scale": None if cmap is None else int(cmap.coded_scale),
        "colour_map_bytes": None if cmap is None else int(cmap.nbytes),
    }


def measure(name: str, photo_path: Path, folder: Path, tile: int) -> dict:
    from terratheme.core.io.images import Bands, read_image
    from terratheme.core.model.project import load_project

    runs = {}
    ctx = get_context("forkserver")
    for kind in ("whole", "shifted", "tiled"):
        out = folder / f"{name}_{kind}.ttproj"
        with ProcessPoolExecutor(1, mp_context=ctx) as pool:
            runs[kind] = pool.submit(_convert, kind, str(photo_path), str(out), tile).result()
        print(f"{name} {kind}: {runs[kind]}", flush=True)
    photo = read_image(photo_path, bands=Bands.PHOTO)
    h, w = photo.shape[:2]
    projects = {k: load_project(folder / f"{name}_{k}.ttproj") for k in runs}
    views = {k: _label_view(p.grid.indices, p.grid.cell, h, w, SHIFT if k == "shifted" else 0)
             for k, p in projects.items()}
    # The shifted run covers the photo from SHIFT on: compare there only.
    cut = -(-SHIFT // STEP)
    result = {"size": [w, h], "tile": tile}
    for kind, project in projects.items():
        entry = {**runs[kind], **_scores(project, photo, SHIFT if kind == "shifted" else 0)}
        if kind != "whole":
            whole, other = views["whole"], views[kind]
            if kind == "shifted":
                whole, other = whole[cut:, cut:], other[cut:, cut:]
            entry["agreement"] = round(agreement(whole, other), 4)
        result[kind] = entry
    print(json.dumps({name: result}, indent=1), flush=True)
    return result


def _repeated(path: Path, photo: Path, repeat: int) -> None:
    """``photo`` repeated ``repeat`` x ``repeat`` times, as a tiled TIFF at ``path``."""
    from terratheme.core.io.images import read_image, write_image

    img = read_image(photo, dtype=np.uint8)[..., :3]
    write_image(path, np.tile(img, (repeat, repeat, 1)), tile=256)


def chart(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in results if isinstance(results[n], dict) and "whole" in results[n]]
    metrics = [("agreement", "agreement with whole"), ("dE8", "dE8 (lower is better)"),
               ("structure_4", "structure 1/4"), ("structure_8", "structure 1/8")]
    fig, axes = plt.subplots(1, len(metrics), figsize=(4 * len(metrics), 3.6), dpi=100)
    kinds = [("whole", "whole photo"), ("shifted", f"whole, shifted {SHIFT} px"),
             ("tiled", "tiled")]
    # An earlier run kept under "before" (the region path before a change): its tiled bars.
    before = results.get("before", {})
    if all(n in before for n in names):
        kinds.append(("before", "tiled, before the change"))
    width = 0.8 / len(kinds)
    for ax, (key, label) in zip(axes, metrics, strict=True):
        for k, (kind, kind_label) in enumerate(kinds):
            values = [(before[n]["tiled"] if kind == "before" else results[n][kind]).get(
                key, np.nan) for n in names]
            ax.bar(np.arange(len(names)) + k * width, values, width, label=kind_label)
        ax.set_xticks(np.arange(len(names)) + width, names, fontsize=8)
        ax.set_title(label, fontsize=9)
        if key == "agreement":
            ax.set_ylim(0.5, 1.0)
        elif key.startswith("structure"):
            ax.set_ylim(0.0, 1.0)
    axes[-1].legend(fontsize=7, loc="lower right")
    fig.suptitle(f"region path (tile {results.get('tile')}) against the whole photo", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--tile", type=int, default=512)
    parser.add_argument("--name", default="region")
    parser.add_argument("--only", help="run only this photo (sample_4x4, dubai_mosaic or "
                        "villas_3x3)")
    args = parser.parse_args()
    sys.path.insert(0, str(REPO / "benchmarks"))
    from mosaic import crop_sources, write_mosaic

    results: dict = {"tile": args.tile, "shift": SHIFT, "step": STEP,
                     "load_average": list(os.getloadavg())}
    # Children fork from a server started now, while this process is small: ru_maxrss
    # survives fork and exec, so children of a large parent would report its size.
    with ProcessPoolExecutor(1, mp_context=get_context("forkserver")) as pool:
        pool.submit(os.getpid).result()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        photos = {"sample_4x4": lambda p: _repeated(p, SAMPLE, 2 if args.quick else 4)}
        if SHARED.is_dir() and not args.quick:
            photos["dubai_mosaic"] = lambda p: write_mosaic(p, 3072, crop_sources(SHARED), 0)
            photos["villas_3x3"] = lambda p: _repeated(p, SHARED / "image_part_005t4.jpg", 3)
        for name, make in photos.items():
            if args.only and name != args.only:
                continue
            path = folder / f"{name}.tif"
            make(path)
            results[name] = measure(name, path, folder, args.tile)
    results["load_average_end"] = list(os.getloadavg())
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(results, indent=1) + "\n")
    chart(results, RESULTS / f"{args.name}.png")


if __name__ == "__main__":
    main()
