"""Benchmark of whole regions: tiled conversion serially and on 1 and 2 workers; streamed render.

Run: ``.venv/bin/python benchmarks/bench_scale.py [--quick] [--sides 8192 32768] [--tile 1024]``

Writes ``benchmarks/results/scale.json`` and ``scale.png``.

Photos: ``side x side`` mosaics of 512-pixel crops of the bundled photo
(``sample_maps/dubai_marina.jpg``) and the shared Dubai photos
(``../shared/data/dubai/images``, when present), written once as tiled
(256) deflate BigTIFFs into a temporary folder.

Each conversion runs ``core.convert.tiled.convert_file_tiled`` (convert's
``--tile`` path with its defaults: unsupervised themes, cell auto, colour
map, shaped borders) in a fresh child process, in three ways measured side
by side on the same photo: the serial path (one process, its numba/OpenCV
pools on every core: the peer), and a local cluster of 1 and of 2 worker
processes (one thread each; ``core.io.cluster.local_cluster``). Reported:
end-to-end and tile-stage throughput (Mpx/s; the tile stages are the grid
and the colour map, the rest runs once on the client), the peak RSS of
every worker process (``ru_maxrss``) and of the client, and whether grid,
themes, colour map and packed layer are identical to the serial run (sha256).

The streamed render (``core.exchange.texture_tiff.write_texture_tiff``,
``render --tiled``) of each converted project runs in a child process:
Mpx/s, peak RSS above start, file bytes. The load average is recorded with
every run, and the CPU seconds of every process: on a shared machine a
session's processes share one CPU share (Linux autogroup), which caps what
2 workers can gain in wall-clock time whatever the code does; CPU seconds
per megapixel show what the parallel path costs. From the figures, an
estimate of the hours and bytes of a 400 x 400 km region at 1 m on N workers.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SHARED = REPO.parent / "shared" / "data" / "dubai" / "images"
SAMPLE = REPO / "sample_maps" / "dubai_marina.jpg"
RESULTS = REPO / "benchmarks" / "results"
BLOCK = 512
REGION_PIXELS = 400_000 * 400_000  # 400 x 400 km at 1 m


def _status_kib(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    return 0


def _peak_rss_mib() -> float:
    """Peak resident memory of this process so far (works on a dask worker too)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _rss_mib() -> float:
    return _status_kib("VmRSS") / 1024


def _cpu_seconds() -> float:
    """CPU time of this process so far, all threads (user + system)."""
    use = resource.getrusage(resource.RUSAGE_SELF)
    return use.ru_utime + use.ru_stime


def make_mosaic(path: Path, side: int, seed: int = 0) -> None:
    """A ``side x side`` RGB tiled BigTIFF of 512-pixel crops of the Dubai photos."""
    from core.io.images import image_info, read_image
    from core.io.tiled_writer import TiledImageWriter

    photos = [SAMPLE] + [p for p in sorted(SHARED.glob("*.jpg")) if SHARED.is_dir()
                         and min(image_info(p).width, image_info(p).height) >= BLOCK]
    rng = np.random.default_rng(seed)
    cache: dict = {}
    with TiledImageWriter(path, side, side, 3, np.uint8, tile=256, bigtiff=True) as out:
        for by in range(0, side, BLOCK):
            band = np.empty((BLOCK, side, 3), np.uint8)
            for bx in range(0, side, BLOCK):
                p = photos[int(rng.integers(len(photos)))]
                if p not in cache:
                    cache.clear()
                    cache[p] = read_image(p, dtype=np.uint8)[..., :3]
                img = cache[p]
                y = int(rng.integers(0, img.shape[0] - BLOCK + 1))
                x = int(rng.integers(0, img.shape[1] - BLOCK + 1))
                band[:, bx : bx + BLOCK] = img[y : y + BLOCK, x : x + BLOCK]
            out.write(0, by, band)


def _sha(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p)
    return h.hexdigest()[:16]


# --------------------------------------------------------------------------- children


def child_convert(args: argparse.Namespace) -> None:
    """One conversion in a fresh process; prints a JSON line."""
    from core.convert.tiled import convert_file_tiled
    from core.fidelity import texture_cost
    from core.io.cluster import local_cluster
    from core.io.images import image_info
    from core.io.tiles import Scheduler
    from core.model.project import save_project
    from core.packing import pack

    info = image_info(args.image)
    start_rss = _rss_mib()
    stages: list[list[float]] = []

    def progress(done: int, total: int) -> None:
        # Stage boundaries: (0, total) opens one, (total, total) closes it.
        if done == 0:
            stages.append([time.perf_counter(), 0.0, total])
        elif done == total:
            stages[-1][1] = time.perf_counter()

    client = local_cluster(args.workers) if args.workers else None
    worker_start = {}
    try:
        if client is not None:
            # Workers ready and their baseline taken before the clock starts.
            worker_start = client.run(_rss_mib)
        worker_cpu0 = client.run(_cpu_seconds) if client is not None else {}
        load0, cpu0 = os.getloadavg(), _cpu_seconds()
        t0 = time.perf_counter()
        project = convert_file_tiled(args.image, None, "auto", tile=args.tile,
                                     scheduler=client or Scheduler.SERIAL, progress=progress)
        seconds = time.perf_counter() - t0
        load1, cpu1 = os.getloadavg(), _cpu_seconds()
        workers = client.run(_peak_rss_mib) if client is not None else {}
        worker_cpu = (sum(client.run(_cpu_seconds).values()) - sum(worker_cpu0.values())
                      if client is not None else 0.0)
    finally:
        if client is not None:
            client.close()
    packed = pack(project.grid.indices, curve="auto").to_bytes()
    cost = texture_cost(project)
    assert cost.grid_bytes == len(packed)
    save_project(args.project, project)
    lib = project.library
    print(json.dumps({
        "seconds": seconds,
        "stage_seconds": [b - a for a, b, _ in stages], "stage_tiles": [t for _, _, t in stages],
        "load_before": load0, "load_after": load1,
        "client_cpu_seconds": cpu1 - cpu0, "worker_cpu_seconds": worker_cpu,
        "client_peak_rss_mib": _peak_rss_mib(), "client_start_rss_mib": start_rss,
        "worker_peak_rss_mib": sorted(workers.values()),
        "worker_start_rss_mib": sorted(worker_start.values()),
        "pixels": info.width * info.height,
        "cell": project.grid.cell[0], "grid_shape": list(project.grid.indices.shape),
        "themes": list(lib.names), "theme_bytes": cost.theme_bytes,
        "colour_map_bytes": cost.colour_map_bytes, "colour_map_scale": project.colour_map.scale,
        "colour_map_shape": list(project.colour_map.pixels.shape[:2]),
        "packed_bytes": len(packed), "project_file_bytes": Path(args.project).stat().st_size,
        "sha": {"grid": _sha(project.grid.indices.tobytes()),
                "themes": _sha(*[t.texture.tobytes() for t in lib], " ".join(lib.names).encode()),
                "colour_map": _sha(project.colour_map.data), "packed": _sha(packed)},
    }))


def child_render(args: argparse.Namespace) -> None:
    """One streamed render of a saved project in a fresh process; prints a JSON line."""
    from core.exchange.texture_tiff import write_texture_tiff
    from core.model.project import load_project

    project = load_project(args.project)
    start = _rss_mib()
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    (w, h), overviews = write_texture_tiff(project, args.out)
    seconds = time.perf_counter() - t0
    print(json.dumps({
        "seconds": seconds, "texels": w * h, "mpx_per_s": w * h / 1e6 / seconds,
        "overviews": overviews, "file_bytes": Path(args.out).stat().st_size,
        "peak_rss_above_start_mib": _status_kib("VmHWM") / 1024 - start,
        "load_before": load0, "load_after": os.getloadavg(),
    }))
    Path(args.out).unlink()


def _child(kind: str, *extra: str) -> dict:
    cmd = [sys.executable, __file__, "--child", kind, *extra]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode:
        sys.stderr.write(done.stderr[-3000:])
        raise SystemExit(f"child {kind} failed")
    return json.loads(done.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------- main parts


def measure(sides: list[int], tile: int, tmp: Path) -> dict:
    records, renders = [], []
    for side in sides:
        image = tmp / f"mosaic_{side}.tif"
        t0 = time.perf_counter()
        make_mosaic(image, side)
        print(f"made {side}^2 tiled BigTIFF in {time.perf_counter() - t0:.0f} s "
              f"({image.stat().st_size / 2**30:.2f} GiB)", flush=True)
        # The three ways side by side; on the smallest photo, 2 workers at other tile sizes.
        runs = [(w, tile) for w in (0, 2, 1)]
        if side == min(sides):
            runs += [(2, t) for t in (tile // 2, tile * 2)]
        for workers, run_tile in runs:
            name = f"{workers} workers" if workers else "serial"
            rec = _child("convert", "--image", str(image), "--tile", str(run_tile),
                         "--workers", str(workers),
                         "--project", str(tmp / f"p_{side}_{workers}_{run_tile}.ttproj"))
            px = rec["pixels"] / 1e6
            tiles_s = sum(rec["stage_seconds"])
            # Tile throughput: photo pixels through both tile stages (grid, colour map).
            rec.update({"side": side, "mode": name, "workers": workers, "tile": run_tile,
                        "mpx_per_s": px / rec["seconds"], "tile_mpx_per_s": px / tiles_s,
                        "client_seconds": rec["seconds"] - tiles_s,
                        "image_file_bytes": image.stat().st_size})
            records.append(rec)
            print(f"  {side}^2 {name:9s} tile {run_tile}: {rec['seconds']:6.1f} s "
                  f"({rec['mpx_per_s']:5.2f} Mpx/s; tile stages "
                  f"{[round(v, 1) for v in rec['stage_seconds']]} s), client peak "
                  f"{rec['client_peak_rss_mib']:.0f} MiB, workers {rec['worker_peak_rss_mib']} "
                  f"MiB, CPU {rec['client_cpu_seconds']:.0f}+{rec['worker_cpu_seconds']:.0f} s, "
                  f"load {rec['load_before'][0]:.1f}->{rec['load_after'][0]:.1f}",
                  flush=True)
        rend = _child("render", "--project", str(tmp / f"p_{side}_0_{tile}.ttproj"),
                      "--out", str(tmp / f"render_{side}.tif"))
        rend["side"] = side
        renders.append(rend)
        print(f"  {side}^2 render --tiled: {rend['seconds']:.1f} s ({rend['mpx_per_s']:.1f} "
              f"Mpx/s), peak +{rend['peak_rss_above_start_mib']:.0f} MiB, "
              f"{rend['file_bytes'] / 2**30:.2f} GiB, {rend['overviews']} overviews", flush=True)
        image.unlink()
    return {"records": records, "renders": renders}


def estimate(result: dict) -> dict:
    """Hours and bytes of a 400 x 400 km region at 1 m from the largest photo's figures."""
    big = max(r["side"] for r in result["records"])
    rec = {r["workers"]: r for r in result["records"]
           if r["side"] == big and r["tile"] == result["tile"]}
    rend = next(r for r in result["renders"] if r["side"] == big)
    px = rec[0]["pixels"]
    # Tile stages per worker: the 1-worker rate, scaled by the measured 2-worker efficiency.
    per_worker = px / sum(rec[1]["stage_seconds"])
    efficiency = (px / sum(rec[2]["stage_seconds"])) / (2 * per_worker)
    client = rec[2]["client_seconds"]
    hours = {n: (client + REGION_PIXELS / (n * per_worker * efficiency)) / 3600
             for n in (1, 2, 8, 32, 128)}
    scale = REGION_PIXELS / px
    cell, cmap_scale = rec[0]["cell"], rec[0]["colour_map_scale"]
    vertices = (400_000 // cell + 1) ** 2
    grid_bytes = vertices  # one byte a vertex, on the client and (colour stage) every worker
    return {
        "assumptions": "tile stages scale to N workers at the measured 2-worker efficiency; "
                       "the client's serial part (theme fit, centre window) is the 2-worker "
                       "run's; the render runs on one machine; bytes scale per vertex, map "
                       "pixel and texel from the largest photo (a mosaic of 512-px crops, "
                       "busier than real land)",
        "measured_on_side": big, "per_worker_tile_mpx_per_s": per_worker / 1e6,
        "worker_peak_rss_mib": max(rec[2]["worker_peak_rss_mib"]) + grid_bytes / 2**20,
        "client_peak_rss_mib": rec[2]["client_peak_rss_mib"] + grid_bytes / 2**20,
        "two_worker_efficiency": efficiency, "client_seconds": client,
        "convert_hours_on_n_workers": hours,
        "render_hours_one_machine": REGION_PIXELS / (rend["mpx_per_s"] * 1e6) / 3600,
        "bytes": {
            "grid_vertices": vertices,
            "packed_layer": rec[0]["packed_bytes"] / np.prod(rec[0]["grid_shape"]) * vertices,
            "colour_map": rec[0]["colour_map_bytes"] / np.prod(rec[0]["colour_map_shape"])
            * REGION_PIXELS / cmap_scale ** 2,
            "themes": rec[0]["theme_bytes"],
            "rendered_geotiff": rend["file_bytes"] * scale,
            "photo_rgb_raw": 3 * REGION_PIXELS,
        },
    }


def chart(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tile = result["tile"]
    recs = [r for r in result["records"] if r["tile"] == tile]
    sides = sorted({r["side"] for r in recs})
    fig, ((ax, axm), (axt, axr)) = plt.subplots(2, 2, figsize=(12, 9), dpi=100)
    width = 0.25
    for k, workers in enumerate((0, 1, 2)):
        rows = [next(r for r in recs if r["side"] == s and r["workers"] == workers)
                for s in sides]
        xs = np.arange(len(sides)) + (k - 1) * width
        label = f"{workers} worker{'s' if workers > 1 else ''}" if workers else "serial (peer)"
        ax.bar(xs, [r["tile_mpx_per_s"] for r in rows], width, label=f"{label}: tile stages")
        ax.plot(xs, [r["mpx_per_s"] for r in rows], "k_", ms=18, mew=2)
        peaks = [max(r["worker_peak_rss_mib"]) if r["worker_peak_rss_mib"]
                 else r["client_peak_rss_mib"] for r in rows]
        axm.plot(sides, peaks, "o-", label=("serial process (client and tiles)" if not workers
                                            else f"each of {workers} worker(s)"))
    axm.plot(sides, [next(r for r in recs if r["side"] == s and r["workers"] == 2)
                     ["client_peak_rss_mib"] for s in sides], "s--", label="client (2 workers)")
    loads = [f"{r['load_before'][0]:.1f}" for r in recs]
    ax.set_xticks(np.arange(len(sides)), [f"{s}²" for s in sides])
    ax.set_ylabel("Mpx/s (bars: tile stages; black: end to end)")
    ax.set_title(f"tiled conversion, tile {tile} (load avg at start: {', '.join(loads)})",
                 fontsize=9)
    ax.legend(fontsize=8)
    axm.set_xscale("log", base=2)
    axm.set_xlabel("photo side (pixels)")
    axm.set_ylabel("peak RSS (MiB)")
    axm.set_ylim(bottom=0)
    axm.set_title(f"peak memory per process vs photo size (tile {tile})")
    axm.legend(fontsize=8)
    small = min(sides)
    by_tile = sorted((r["tile"], max(r["worker_peak_rss_mib"])) for r in result["records"]
                     if r["side"] == small and r["workers"] == 2)
    axt.plot(*zip(*by_tile, strict=True), "o-", label=f"each of 2 workers, {small}² photo")
    axt.set_xscale("log", base=2)
    axt.set_xlabel("tile side (pixels)")
    axt.set_ylabel("peak RSS (MiB)")
    axt.set_ylim(bottom=0)
    axt.set_title("peak memory per worker vs tile size")
    axt.legend(fontsize=8)
    rend = result["renders"]
    axr.plot([r["side"] for r in rend], [r["peak_rss_above_start_mib"] for r in rend], "o-",
             label="render --tiled: peak RSS above start (MiB)")
    axr.plot([r["side"] for r in rend], [r["file_bytes"] / 2**20 for r in rend], "s--",
             label="its GeoTIFF with overviews (MiB)")
    axr.set_xscale("log", base=2)
    axr.set_yscale("log")
    axr.set_xlabel("photo side (pixels)")
    axr.set_title("streamed render: memory vs output size")
    axr.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2048^2 and 4096^2 photos only")
    parser.add_argument("--sides", type=int, nargs="+", default=[8192, 32768])
    parser.add_argument("--tile", type=int, default=1024)
    parser.add_argument("--child", choices=["convert", "render"])
    parser.add_argument("--image")
    parser.add_argument("--workers", type=int, default=0)
    parser.add_argument("--project")
    parser.add_argument("--out")
    args = parser.parse_args()
    if args.child == "convert":
        child_convert(args)
        return
    if args.child == "render":
        child_render(args)
        return
    sides = [2048, 4096] if args.quick else args.sides
    RESULTS.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="bench_scale_") as tmp:
        result = {"tile": args.tile, "cpus": os.cpu_count(), **measure(sides, args.tile,
                                                                       Path(tmp))}
    result["estimate_400km"] = estimate(result)
    name = "scale_quick" if args.quick else "scale"
    (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=1))
    chart(result, RESULTS / f"{name}.png")
    print(json.dumps(result["estimate_400km"], indent=1))
    print(f"wrote {RESULTS / name}.json and .png")


if __name__ == "__main__":
    main()
