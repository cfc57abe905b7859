"""Benchmark of whole regions: tiled conversion serially and on 1 and 2 workers; streamed render.

Run: ``.venv/bin/python benchmarks/bench_scale.py [--quick] [--sides 4096 16384 32768]
[--tile 1024] [--repeat-sides 16384] [--one-worker-max 16384]``

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
per megapixel show what the parallel path costs. Serial and 2-worker runs
alternate (serial, 2, 1 worker, then 2 and serial again on ``--repeat-sides``);
``pairs`` ratios each 2-worker run to the serial run next to it in time. From
the figures, an estimate of the hours and bytes of a 400 x 400 km region at
1 m on N workers (``estimate_400km``). Results kept: ``scale`` (4096, 16384,
32768), ``scale_8192`` and ``scale_8192_tile2048`` (``--name``, a quiet hour).
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

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SHARED = REPO.parent / "shared" / "data" / "dubai" / "images"
SAMPLE = REPO / "sample_maps" / "dubai_marina.jpg"
RESULTS = REPO / "benchmarks" / "results"
sys.path.insert(0, str(REPO / "benchmarks"))
from scale_chart import chart  # noqa: E402
from scale_estimate import estimate, pairs  # noqa: E402


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


def _import_core() -> None:
    """Import the tile jobs' code (what ``core.io.cluster.warm_up`` starts on a worker)."""
    import terratheme.core.convert.colour_fit
    import terratheme.core.convert.tiled  # noqa: F401


def _cpu_seconds() -> float:
    """CPU time of this process so far, all threads (user + system)."""
    use = resource.getrusage(resource.RUSAGE_SELF)
    return use.ru_utime + use.ru_stime


def make_mosaic(path: Path, side: int, seed: int = 0) -> None:
    """A ``side x side`` RGB tiled BigTIFF of 512-pixel crops of the Dubai photos."""
    # Imported here: the children measure their memory before core is loaded.
    from mosaic import crop_sources, write_mosaic

    write_mosaic(path, side, [SAMPLE] + crop_sources(SHARED), seed, bigtiff=True)


def _sha(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p)
    return h.hexdigest()[:16]


# --------------------------------------------------------------------------- children


def child_convert(args: argparse.Namespace) -> None:
    """One conversion in a fresh process; prints a JSON line."""
    from terratheme.core.convert.tiled import convert_file_tiled
    from terratheme.core.fidelity import texture_cost
    from terratheme.core.io.cluster import local_cluster
    from terratheme.core.io.images import image_info
    from terratheme.core.io.tiles import Scheduler
    from terratheme.core.model.project import save_project
    from terratheme.core.packing import pack

    info = image_info(args.image)
    start_rss = _rss_mib()
    stages: list[list[float]] = []

    client = local_cluster(args.workers) if args.workers else None
    marks: list[dict] = []

    def cpu_now() -> dict:
        # Client and worker CPU seconds and the load at a stage boundary.
        workers = sum(client.run(_cpu_seconds).values()) if client is not None else 0.0
        return {"t": time.perf_counter(), "client_cpu": _cpu_seconds(), "worker_cpu": workers,
                "load": os.getloadavg()[0]}

    def progress(done: int, total: int) -> None:
        # Stage boundaries: (0, total) opens one, (total, total) closes it.
        if done == 0:
            stages.append([time.perf_counter(), 0.0, total])
            marks.append({"start": cpu_now()})
        elif done == total:
            stages[-1][1] = time.perf_counter()
            marks[-1]["end"] = cpu_now()

    worker_start = {}
    try:
        if client is not None:
            # Workers ready (terratheme imported, as a running cluster's are) and their
            # baseline taken before the clock starts.
            client.run(_import_core)
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
    # CPU seconds inside the tile stages (the part that runs on the workers).
    stage_cpu = [{"client": m["end"]["client_cpu"] - m["start"]["client_cpu"],
                  "workers": m["end"]["worker_cpu"] - m["start"]["worker_cpu"],
                  "load": [m["start"]["load"], m["end"]["load"]]} for m in marks]
    packed = pack(project.grid.indices, curve="auto").to_bytes()
    cost = texture_cost(project)
    assert cost.grid_bytes == len(packed)
    save_project(args.project, project)
    lib = project.library
    print(json.dumps({
        "seconds": seconds,
        "stage_seconds": [b - a for a, b, _ in stages], "stage_tiles": [t for _, _, t in stages],
        "stage_cpu_seconds": stage_cpu,
        "load_before": load0, "load_after": load1,
        "client_cpu_seconds": cpu1 - cpu0, "worker_cpu_seconds": worker_cpu,
        "client_peak_rss_mib": _peak_rss_mib(), "client_start_rss_mib": start_rss,
        "worker_peak_rss_mib": sorted(workers.values()),
        "worker_start_rss_mib": sorted(worker_start.values()),
        "pixels": info.width * info.height,
        "cell": project.grid.cell[0], "grid_shape": list(project.grid.indices.shape),
        "themes": list(lib.names), "theme_bytes": cost.theme_bytes,
        "colour_map_bytes": cost.colour_map_bytes,
        "colour_map_scale": project.colour_map.coded_scale,
        "colour_map_shape": list(project.colour_map.pixels.shape[:2]),
        "packed_bytes": len(packed), "project_file_bytes": Path(args.project).stat().st_size,
        "sha": {"grid": _sha(project.grid.indices.tobytes()),
                "themes": _sha(*[t.texture.tobytes() for t in lib], " ".join(lib.names).encode()),
                "colour_map": _sha(project.colour_map.data or b"",
                                   *(project.colour_map.tiles or ())),
                "packed": _sha(packed)},
    }))


def child_render(args: argparse.Namespace) -> None:
    """One streamed render of a saved project in a fresh process; prints a JSON line."""
    from terratheme.core.exchange.texture_tiff import write_texture_tiff
    from terratheme.core.model.project import load_project

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


def _convert_run(image: Path, side: int, workers: int, tile: int, tmp: Path) -> dict:
    """One conversion child and its derived figures."""
    name = f"{workers} workers" if workers else "serial"
    rec = _child("convert", "--image", str(image), "--tile", str(tile), "--workers", str(workers),
                 "--project", str(tmp / f"p_{side}_{workers}_{tile}.ttproj"))
    px = rec["pixels"] / 1e6
    tiles_s = sum(rec["stage_seconds"])
    client_cpu = sum(c["client"] for c in rec["stage_cpu_seconds"])
    tile_cpu = client_cpu + sum(c["workers"] for c in rec["stage_cpu_seconds"])
    # Tile throughput: photo pixels through both tile stages (grid, colour map).
    rec.update({"side": side, "mode": name, "workers": workers, "tile": tile,
                "mpx_per_s": px / rec["seconds"], "tile_mpx_per_s": px / tiles_s,
                "client_seconds": rec["seconds"] - tiles_s,
                "tile_cpu_s_per_mpx": tile_cpu / px,
                "client_tile_cpu_s_per_mpx": client_cpu / px if workers else None,
                "cores_obtained": tile_cpu / tiles_s,
                "image_file_bytes": image.stat().st_size})
    print(f"  {side}^2 {name:9s} tile {tile}: {rec['seconds']:6.1f} s "
          f"({rec['mpx_per_s']:5.2f} Mpx/s; tile stages "
          f"{[round(v, 1) for v in rec['stage_seconds']]} s, {rec['tile_mpx_per_s']:.2f} Mpx/s, "
          f"{rec['tile_cpu_s_per_mpx']:.2f} CPU s/Mpx on {rec['cores_obtained']:.2f} cores), "
          f"client peak {rec['client_peak_rss_mib']:.0f} MiB, workers "
          f"{[round(v) for v in rec['worker_peak_rss_mib']]} MiB, "
          f"load {rec['load_before'][0]:.1f}->{rec['load_after'][0]:.1f}", flush=True)
    return rec


def measure(sides: list[int], tile: int, tmp: Path, one_worker_max: int,
            repeat_sides: list[int], save, tile_variants: bool = True) -> dict:
    result = {"records": [], "renders": []}
    for side in sides:
        image = tmp / f"mosaic_{side}.tif"
        t0 = time.perf_counter()
        make_mosaic(image, side)
        print(f"made {side}^2 tiled BigTIFF in {time.perf_counter() - t0:.0f} s "
              f"({image.stat().st_size / 2**30:.2f} GiB)", flush=True)
        # Serial and 2 workers interleaved (each 2-worker run next to a serial one), 1 worker.
        runs = [(0, tile), (2, tile)]
        if side <= one_worker_max:
            runs.append((1, tile))
        if side in repeat_sides:
            runs += [(2, tile), (0, tile)]
        if side == min(sides) and tile_variants:
            runs += [(2, t) for t in (tile // 2, tile * 2)]
        for order, (workers, run_tile) in enumerate(runs):
            rec = _convert_run(image, side, workers, run_tile, tmp)
            rec["order"] = order
            serial = [r for r in [*result["records"], rec] if r["side"] == side
                      and r["workers"] == 0 and r["tile"] == tile]
            # Grid, themes, colour map and packed layer against the serial run's (sha256):
            # at the same tile (the claim), and other tiles against the main tile's (tiles
            # agree when the overlap covers the classifier's support).
            key = "identical_to_serial" if run_tile == tile else "same_as_serial_at_main_tile"
            rec[key] = rec["sha"] == serial[0]["sha"]
            result["records"].append(rec)
            save(result)
        rend = _child("render", "--project", str(tmp / f"p_{side}_0_{tile}.ttproj"),
                      "--out", str(tmp / f"render_{side}.tif"))
        rend["side"] = side
        result["renders"].append(rend)
        print(f"  {side}^2 render --tiled: {rend['seconds']:.1f} s ({rend['mpx_per_s']:.1f} "
              f"Mpx/s), peak +{rend['peak_rss_above_start_mib']:.0f} MiB, "
              f"{rend['file_bytes'] / 2**30:.2f} GiB, {rend['overviews']} overviews", flush=True)
        for stale in tmp.glob(f"p_{side}_*"):
            stale.unlink()
        image.unlink()
        save(result)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2048^2 and 4096^2 photos only")
    parser.add_argument("--sides", type=int, nargs="+", default=[8192, 32768])
    parser.add_argument("--tile", type=int, default=1024)
    parser.add_argument("--one-worker-max", type=int, default=16384,
                        help="largest side run on 1 worker too")
    parser.add_argument("--repeat-sides", type=int, nargs="*", default=[16384],
                        help="sides whose serial and 2-worker runs are repeated, interleaved")
    parser.add_argument("--no-tile-variants", action="store_true",
                        help="no 2-worker runs at half and twice the tile on the smallest side")
    parser.add_argument("--name", help="results name (default scale, or scale_quick)")
    parser.add_argument("--replot", action="store_true",
                        help="recompute pairs, estimate and chart from the saved JSON")
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
    repeat = [4096] if args.quick else args.repeat_sides
    RESULTS.mkdir(parents=True, exist_ok=True)
    name = args.name or ("scale_quick" if args.quick else "scale")
    head = {"tile": args.tile, "cpus": os.cpu_count(), "sides": sides,
            "note": "2 cores shared with other sessions' processes (load averages recorded); "
                    "Linux autogroup gives this session's processes (client and workers) one "
                    "share of the CPU, so wall-clock ratios show that share, CPU seconds per "
                    "megapixel what each path costs"}

    def save(part: dict) -> None:
        # Partial results after every run: a long run stopped early keeps its figures.
        full = {**head, **part, "pairs": pairs({**head, **part})}
        (RESULTS / f"{name}.json").write_text(json.dumps(full, indent=1))

    if args.replot:
        # A run stopped after some sides: its partial figures, summed up again.
        result = json.loads((RESULTS / f"{name}.json").read_text())
    else:
        with tempfile.TemporaryDirectory(prefix="bench_scale_") as tmp:
            result = {**head, **measure(sides, args.tile, Path(tmp), args.one_worker_max,
                                        repeat, save, not args.no_tile_variants)}
    result["pairs"] = pairs(result)
    result["estimate_400km"] = estimate(result)
    (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=1))
    chart(result, RESULTS / f"{name}.png")
    print(json.dumps(result["pairs"], indent=1))
    print(json.dumps(result["estimate_400km"], indent=1))
    print(f"wrote {RESULTS / name}.json and .png")


if __name__ == "__main__":
    main()
