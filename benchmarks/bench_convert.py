"""Benchmark of the convert pipeline: agreement and bytes vs cell size; tiled-path peak memory.

Run: ``.venv/bin/python benchmarks/bench_convert.py [--quick] [--only-a]``

Writes ``benchmarks/results/convert.json`` and ``convert.png``.

Part A (Dubai sample photo, ``sample_maps/dubai_marina.jpg``, with its mask
from ``../shared/data/dubai`` when present): the agreement curve of
:func:`core.convert.cell_choice.choose_cell_size` for the unsupervised labels and
for the ground-truth mask, the grid's bytes (1 per vertex; packed along a
space-filling curve) against the peer "the full-resolution label map packed
the same way", and the end-to-end ``convert_photo`` time.

Part B (peak memory): photos tiled into 2048^2 .. 16384^2 tiled TIFFs (temp
dir). Each measurement runs in a fresh child process and reports its peak
resident memory (``VmHWM``) above the resident memory after imports, plus
the tracemalloc peak (numpy allocations). Peers in the same run: the whole-
image path (read_image + classify + vote_grid) against the tiled path
(:func:`core.convert.tiled.grid_from_file`), with a per-pixel nearest-colour
classifier (fast, so every size and tile is measured; no context needed) and
with the trained random forest of ``core.classify`` (the real pipeline; 32
pixels of context here, where the product default is 128, see
``core.convert.tiled.DEFAULT_OVERLAP``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from mosaic import crop_sources, write_mosaic  # noqa: E402

SHARED = REPO.parent / "shared" / "data" / "dubai"
SAMPLE = REPO / "sample_maps" / "dubai_marina.jpg"
SAMPLE_MASK = SHARED / "masks" / "image_part_004t5.png"
RESULTS = REPO / "benchmarks" / "results"


def _status_kib(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    return 0


# --------------------------------------------------------------------------- part A


def part_a(quick: bool) -> dict:
    from terratheme.core.classify import classify_unsupervised
    from terratheme.core.convert.cell_choice import choose_cell_size
    from terratheme.core.convert.labels_to_grid import vote_grid
    from terratheme.core.convert.photo import ConvertOptions, convert_photo
    from terratheme.core.io.images import read_image
    from terratheme.core.packing import pack

    photo = read_image(SAMPLE)
    # Warm-up on a crop: numba kernels compile on first use, not part of the timings.
    convert_photo(photo[:96, :96], ConvertOptions(cell=8))
    t0 = time.perf_counter()
    labels = classify_unsupervised(photo).labels
    t_classify = time.perf_counter() - t0
    sources = {"unsupervised labels": labels}
    if SAMPLE_MASK.is_file():
        mask = read_image(SAMPLE_MASK)[..., 0]
        sources["ground-truth mask"] = mask
    out: dict = {"photo": SAMPLE.name, "size": list(photo.shape[1::-1]), "curves": {}}
    for name, lab in sources.items():
        t0 = time.perf_counter()
        choice = choose_cell_size(lab, 0.9, sample_pixels=None)
        t_choose = time.perf_counter() - t0
        full_packed = len(pack(lab, curve="auto").to_bytes())
        points = []
        for p in choice.curve:
            grid = vote_grid(lab, (p.cell, p.cell))
            packed = len(pack(grid, curve="auto").to_bytes())
            points.append({"cell": p.cell, "agreement": p.agreement, "grid_bytes": p.grid_bytes,
                           "packed_bytes": packed,
                           "packed_ratio_vs_full_res": full_packed / packed})
        out["curves"][name] = {
            "chosen_cell": choice.cell[0], "agreement": choice.agreement, "target": 0.9,
            "choose_seconds": t_choose, "full_res_packed_bytes": full_packed, "points": points,
        }
    t0 = time.perf_counter()
    res = convert_photo(photo, ConvertOptions())
    t_convert = time.perf_counter() - t0
    out["convert_seconds"] = t_convert
    out["classify_seconds"] = t_classify
    out["convert_over_classify"] = t_convert / t_classify
    out["choose_over_classify"] = (
        out["curves"]["unsupervised labels"]["choose_seconds"] / t_classify
    )
    out["convert_cell"] = res.project.grid.cell[0]
    out["convert_agreement"] = res.agreement
    return out


# --------------------------------------------------------------------------- part B


def make_big_tiff(path: Path, side: int, seed: int = 0) -> None:
    """A ``side x side`` RGB tiled TIFF made of 512-pixel crops of the Dubai photos."""
    photos = crop_sources(SHARED / "images") or [SAMPLE]
    write_mosaic(path, side, photos, seed, compression="zip")


def _nearest_colour_fn(centres: np.ndarray):
    cen = centres.astype(np.float32)

    def classify(pixels: np.ndarray) -> np.ndarray:
        # Row chunks keep the classifier's own temporaries small on any image.
        out = np.empty(pixels.shape[:2], np.uint8)
        for r in range(0, pixels.shape[0], 256):
            px = pixels[r : r + 256, :, :3].astype(np.float32)
            # Squared distance to each centre (elementwise: BLAS is slow on 3-wide products).
            d = np.stack([((px - c) ** 2).sum(axis=2) for c in cen])
            out[r : r + 256] = np.argmin(d, axis=0) + 1
        return out

    return classify


def child(args: argparse.Namespace) -> None:
    """One measurement in a fresh process; prints a JSON line."""
    import tracemalloc

    from terratheme.core.classify import Classifier
    from terratheme.core.convert.labels_to_grid import vote_grid
    from terratheme.core.convert.tiled import grid_from_file
    from terratheme.core.io.images import read_image

    if args.classifier == "forest":
        model = Classifier.load(args.model)

        def classify(p):
            return model.predict(p).labels
        overlap = 32
    else:
        classify = _nearest_colour_fn(np.array(json.loads(args.centres)))
        overlap = 0
    base = _status_kib("VmRSS")
    tracemalloc.start()
    t0 = time.perf_counter()
    if args.mode == "whole":
        img = read_image(args.image)
        grid = vote_grid(classify(img), (16, 16))
    else:
        grid = grid_from_file(args.image, 16, classify, tile=args.tile, overlap=overlap).indices
    seconds = time.perf_counter() - t0
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(json.dumps({
        "peak_rss_above_start_mib": (_status_kib("VmHWM") - base) / 1024,
        "tracemalloc_peak_mib": traced_peak / 2**20, "seconds": seconds,
        "grid_checksum": int(grid.astype(np.int64).sum()), "grid_shape": list(grid.shape),
    }))


def _measure(mode, image, tile, classifier, extra) -> dict:
    cmd = [sys.executable, __file__, "--child", mode, "--image", str(image), "--tile", str(tile),
           "--classifier", classifier, *extra]
    done = subprocess.run(cmd, capture_output=True, text=True, check=True)
    rec = json.loads(done.stdout.strip().splitlines()[-1])
    side = int(Path(image).stem.split("_")[-1])
    rec.update({"mode": mode, "side": side, "tile": tile if mode != "whole" else None,
                "classifier": classifier, "mpx_per_s": side * side / 1e6 / rec["seconds"]})
    print(f"  {classifier:8s} {mode:6s} {side:5d}^2 tile {tile:5d}: peak +"
          f"{rec['peak_rss_above_start_mib']:7.1f} MiB, {rec['seconds']:6.1f} s", flush=True)
    return rec


def part_b(quick: bool) -> dict:
    import cv2
    from terratheme.core.classify import train_classifier
    from terratheme.core.io.images import read_image

    photo = read_image(SAMPLE, dtype=np.uint8)[..., :3]
    # Nearest-colour classifier: 5 k-means colour centres of the sample (OpenCV).
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 20, 1.0)
    _, _, centres = cv2.kmeans(photo.reshape(-1, 3).astype(np.float32)[::7], 5, None, crit, 2,
                               cv2.KMEANS_PP_CENTERS)
    cen_arg = ["--centres", json.dumps(centres.round(2).tolist())]
    sides = [2048, 4096] if quick else [2048, 4096, 8192, 16384]
    records = []
    with tempfile.TemporaryDirectory(prefix="bench_convert_") as tmp:
        tmp = Path(tmp)
        model_args: list[str] = []
        if SAMPLE_MASK.is_file():
            mask = read_image(SAMPLE_MASK)[..., 0]
            model = train_classifier([(photo, np.where(mask > 5, 0, mask))])
            model.save(tmp / "forest.model")
            model_args = ["--model", str(tmp / "forest.model")]
        images = {}
        for side in sides:
            t0 = time.perf_counter()
            images[side] = tmp / f"tiled_{side}.tif"
            make_big_tiff(images[side], side)
            print(f"made {side}^2 tiled TIFF in {time.perf_counter() - t0:.1f} s "
                  f"({images[side].stat().st_size / 2**20:.0f} MiB)", flush=True)
        big = images[sides[-1]]
        # Peer pair 1: whole-image vs tiled (tile 1024) at every size, nearest-colour.
        for side in sides:
            if side <= 8192:
                records.append(_measure("whole", images[side], 0, "colour", cen_arg))
            records.append(_measure("tiled", images[side], 1024, "colour", cen_arg))
        # Tile sizes on the largest image.
        for tile in [256, 4096]:
            records.append(_measure("tiled", big, tile, "colour", cen_arg))
        # Peer pair 2: the trained random forest, whole vs tiled.
        if model_args:
            for side in sides:
                if side <= 4096:
                    records.append(_measure("whole", images[side], 0, "forest", model_args))
                records.append(_measure("tiled", images[side], 1024, "forest", model_args))
    return {"records": records, "sides": sides}


# --------------------------------------------------------------------------- chart


def chart(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5), dpi=100)
    ax, axb, axm, axt = axes.ravel()
    a = result["part_a"]
    for name, cur in a["curves"].items():
        cells = [p["cell"] for p in cur["points"]]
        ax.plot(cells, [p["agreement"] for p in cur["points"]], "o-",
                label=f"{name} (chosen cell {cur['chosen_cell']})")
        axb.plot(cells, [p["packed_bytes"] for p in cur["points"]], "o-",
                 label=f"grid packed, {name}")
        axb.axhline(cur["full_res_packed_bytes"], ls=":", lw=1, color=ax.lines[-1].get_color(),
                    label=f"peer: full-res labels packed, {name}")
    cells = [p["cell"] for p in next(iter(a["curves"].values()))["points"]]
    axb.plot(cells, [p["grid_bytes"] for p in next(iter(a["curves"].values()))["points"]],
             "k--", lw=1, label="grid raw (1 byte / vertex)")
    ax.axhline(0.9, color="grey", ls="--", lw=1, label="target 0.9")
    for a_ in (ax, axb):
        a_.set_xscale("log", base=2)
        a_.set_xlabel("cell size (texels)")
    ax.set_ylabel("label agreement of the grid's label view")
    ax.set_title(f"{a['photo']} {a['size'][0]}x{a['size'][1]}: agreement vs cell size")
    ax.legend(fontsize=8)
    axb.set_yscale("log")
    axb.set_ylabel("bytes")
    axb.set_title("index bytes vs cell size")
    axb.legend(fontsize=7)
    recs = result["part_b"]["records"]
    for clf, mode, style in [("colour", "whole", "s--"), ("colour", "tiled", "o-"),
                             ("forest", "whole", "s--"), ("forest", "tiled", "o-")]:
        pts = [(r["side"], r["peak_rss_above_start_mib"]) for r in recs
               if r["classifier"] == clf and r["mode"] == mode and (r["tile"] in (None, 1024))]
        if pts:
            xs, ys = zip(*sorted(pts), strict=True)
            axm.plot(xs, ys, style, label=f"{mode} image, {clf} classifier"
                     + (" (tile 1024)" if mode == "tiled" else ""))
    axm.set_xscale("log", base=2)
    axm.set(yscale="log", xlabel="image side (pixels)", ylabel="peak RSS above start (MiB)",
            title="peak memory vs image size")
    axm.legend(fontsize=8)
    big = max(result["part_b"]["sides"])
    pts = sorted((r["tile"], r["peak_rss_above_start_mib"]) for r in recs
                 if r["side"] == big and r["mode"] == "tiled" and r["classifier"] == "colour")
    if pts:
        xs, ys = zip(*pts, strict=True)
        axt.plot(xs, ys, "o-", label=f"tiled, {big}^2 image")
    axt.set_xscale("log", base=2)
    axt.set(yscale="log", xlabel="tile side (pixels)", ylabel="peak RSS above start (MiB)",
            title=f"peak memory vs tile size ({big}x{big} image)")
    axt.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small images only")
    parser.add_argument("--only-a", action="store_true",
                        help="rerun part A only, keeping part B of the existing convert.json")
    parser.add_argument("--child", choices=["whole", "tiled"])
    parser.add_argument("--image")
    parser.add_argument("--tile", type=int, default=1024)
    parser.add_argument("--classifier", default="colour")
    parser.add_argument("--centres")
    parser.add_argument("--model")
    args = parser.parse_args()
    if args.child:
        args.mode = args.child
        child(args)
        return
    RESULTS.mkdir(parents=True, exist_ok=True)
    print("part A: agreement and bytes vs cell size", flush=True)
    result = {"part_a": part_a(args.quick)}
    if args.only_a:
        result["part_b"] = json.loads((RESULTS / "convert.json").read_text())["part_b"]
    else:
        print("part B: peak memory, tiled vs whole", flush=True)
        result["part_b"] = part_b(args.quick)
    (RESULTS / "convert.json").write_text(json.dumps(result, indent=1))
    chart(result, RESULTS / "convert.png")
    print(f"wrote {RESULTS / 'convert.json'} and convert.png")


if __name__ == "__main__":
    main()
