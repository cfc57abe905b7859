"""Benchmark of the client's cost per task on a local dask cluster: one tile a task or several.

Run: ``.venv/bin/python benchmarks/bench_cluster_tasks.py [--side 4096] [--tiles 512 1024]
[--idle] [--encode]``

Writes ``benchmarks/results/scale_tasks.json`` (``--idle``: ``scale_idle.json``, ``--encode``:
``scale_encode.json``).

``--idle``: the CPU an idle 2-worker local cluster costs (client process, workers) over
15 s, with ``core.io.cluster.QUIET_LOCAL`` and with dask's memory-monitor and
system-monitor intervals (100 ms, 500 ms), alternately. ``--encode``: a colour map of
4 JPEG XL tiles (2048^2 each, the single-image limit forced low) encoded on the client
(``ColourMap.encode``) and on 2 workers (``ClusterTiles``): wall and client CPU seconds,
and whether the bytes are identical.

``core.io.cluster.map_ordered`` runs several consecutive items a task
(``MAX_GROUP``, guided); ``MAX_GROUP = 1`` is the one-item-a-task path it
replaced. Both run alternately in one process on one 2-worker local cluster
(the scheduler runs in this process, so its CPU is the client's): (a) 400
trivial items, (b) the grid stage of a tiled conversion
(``core.convert.tiled.grid_from_file``, unsupervised themes) on a ``side^2``
mosaic at each tile size. Reported: the client's CPU seconds per item and per
task, wall seconds, and whether the grids are identical (sha256).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))
SHARED = REPO.parent / "shared" / "data" / "dubai" / "images"
SAMPLE = REPO / "sample_maps" / "dubai_marina.jpg"
RESULTS = REPO / "benchmarks" / "results"

import terratheme.core.io.cluster as cluster  # noqa: E402
from terratheme.core.convert.region_sample import fit_unsupervised_region  # noqa: E402
from terratheme.core.convert.tile_vote import PredictLabels  # noqa: E402
from terratheme.core.convert.tiled import grid_from_file  # noqa: E402


def _cpu() -> float:
    use = resource.getrusage(resource.RUSAGE_SELF)
    return use.ru_utime + use.ru_stime


def plus_one(item: int, shared: int) -> int:
    """A trivial task."""
    return item + shared


def _counting(client):
    """Count the tasks submitted to ``client`` (patched onto it)."""
    counts = [0]
    real = client.submit

    def submit(*args, **kw):
        counts[0] += 1
        return real(*args, **kw)

    client.submit = submit
    return counts


def _run(what, client, counts, group_max: int, items: int) -> dict:
    cluster.MAX_GROUP = group_max
    counts[0] = 0
    load, cpu0, t0 = os.getloadavg()[0], _cpu(), time.perf_counter()
    out = what()
    wall, cpu = time.perf_counter() - t0, _cpu() - cpu0
    return {"max_group": group_max, "items": items, "tasks": counts[0], "wall_s": wall,
            "client_cpu_s": cpu, "client_cpu_ms_per_item": 1e3 * cpu / items,
            "client_cpu_ms_per_task": 1e3 * cpu / counts[0], "load": load, "out": out}


def idle(repeat: int) -> dict:
    """Cores an idle local cluster costs, quiet monitors or dask's defaults, alternately."""
    quiet = dict(cluster.QUIET_LOCAL)
    default = {**quiet, "distributed.worker.memory.monitor-interval": "100ms",
               "distributed.admin.system-monitor.interval": "500ms"}
    records = []
    for rep in range(repeat):
        for name, settings in [("quiet", quiet), ("dask monitors", default)][::1 - 2 * (rep % 2)]:
            cluster.QUIET_LOCAL = settings
            with cluster.local_cluster(2) as client:
                time.sleep(3)
                w0, c0, t0 = sum(client.run(_cpu).values()), _cpu(), time.perf_counter()
                time.sleep(15)
                w1, c1, t1 = sum(client.run(_cpu).values()), _cpu(), time.perf_counter()
            records.append({"settings": name, "client_cores": (c1 - c0) / (t1 - t0),
                            "worker_cores": (w1 - w0) / (t1 - t0), "load": os.getloadavg()[0]})
            print(records[-1], flush=True)
    cluster.QUIET_LOCAL = quiet
    return {"records": records}


def encode(repeat: int) -> dict:
    """A 4-tile JPEG XL colour map encoded on the client and on 2 workers."""
    import cv2
    import numpy as np
    import terratheme.core.model.colour_map as colour_map
    from terratheme.core.convert.colour_fit import ClusterTiles

    rng = np.random.default_rng(0)
    side = 4096
    gains = cv2.resize(rng.integers(100, 160, (side // 32, side // 32, 3), dtype=np.uint8),
                       (side, side), interpolation=cv2.INTER_CUBIC)
    gains = np.clip(gains.astype(int) + rng.integers(-2, 3, gains.shape), 0, 255)
    gains = gains.astype(np.uint8)
    colour_map.ONE_IMAGE_LIMITS = {**colour_map.ONE_IMAGE_LIMITS, "jpegxl": (2048, 2048**2)}
    colour_map.MAP_TILE = 2048
    records = []
    with cluster.local_cluster(2) as client:
        cluster.warm_up(client, ["terratheme.core.convert.colour_fit"])
        for rep in range(repeat):
            for where in ("client", "2 workers")[::1 - 2 * (rep % 2)]:
                run = ClusterTiles(client) if where != "client" else None
                load, c0, t0 = os.getloadavg()[0], _cpu(), time.perf_counter()
                cmap = colour_map.ColourMap.encode(gains, 16, "jpegxl", 99, run=run)
                records.append({"where": where, "wall_s": time.perf_counter() - t0,
                                "client_cpu_s": _cpu() - c0, "load": load,
                                "tiles": len(cmap.tiles),
                                "sha": hashlib.sha256(b"".join(cmap.tiles)).hexdigest()[:16]})
                print(records[-1], flush=True)
    return {"records": records, "identical": len({r["sha"] for r in records}) == 1}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, default=4096)
    parser.add_argument("--tiles", type=int, nargs="+", default=[512, 1024])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--idle", action="store_true")
    parser.add_argument("--encode", action="store_true")
    args = parser.parse_args()
    if args.idle or args.encode:
        name, result = (("scale_idle", idle(args.repeat)) if args.idle
                        else ("scale_encode", encode(args.repeat)))
        RESULTS.mkdir(parents=True, exist_ok=True)
        (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=1))
        return
    from mosaic import crop_sources, write_mosaic

    grouped = cluster.MAX_GROUP
    records = []
    with tempfile.TemporaryDirectory(prefix="bench_tasks_") as tmp:
        photo = Path(tmp) / "mosaic.tif"
        write_mosaic(photo, args.side, [SAMPLE] + crop_sources(SHARED), 0, bigtiff=True)
        model = fit_unsupervised_region(photo)
        classify = PredictLabels(model)
        with cluster.local_cluster(2) as client:
            counts = _counting(client)
            cluster.warm_up(client, ["terratheme.core.convert.tiled"])
            n = 400

            def trivial():
                got = []
                cluster.map_ordered(client, plus_one, list(range(n)), 1,
                                    lambda i, r: got.append(r))
                return hashlib.sha256(str(got).encode()).hexdigest()[:16]

            # Warm: workers import, numba loads its kernels.
            grid_from_file(photo, 16, classify, tile=1024, overlap=model.context_pixels,
                           scheduler=client)
            for rep in range(args.repeat):
                for g in (1, grouped) if rep % 2 == 0 else (grouped, 1):
                    rec = _run(trivial, client, counts, g, n)
                    records.append({"kind": "trivial", "rep": rep, **rec})
                    for tile in args.tiles:
                        tiles = (-(-args.side // tile)) ** 2

                        def grid(tile=tile):
                            out = grid_from_file(photo, 16, classify, tile=tile,
                                                 overlap=model.context_pixels,
                                                 scheduler=client)
                            return hashlib.sha256(out.indices.tobytes()).hexdigest()[:16]

                        rec = _run(grid, client, counts, g, tiles)
                        records.append({"kind": f"grid tile {tile}", "rep": rep, **rec})
                    for r in records[-1 - len(args.tiles):]:
                        print(f"{r['kind']:14s} max_group {r['max_group']}: {r['tasks']:4d} "
                              f"tasks for {r['items']} items, client "
                              f"{r['client_cpu_ms_per_item']:.2f} ms/item "
                              f"({r['client_cpu_ms_per_task']:.2f} ms/task), wall "
                              f"{r['wall_s']:.2f} s, load {r['load']:.1f}", flush=True)
    cluster.MAX_GROUP = grouped
    kinds = sorted({r["kind"] for r in records})
    summary = {}
    for kind in kinds:
        one = [r for r in records if r["kind"] == kind and r["max_group"] == 1]
        many = [r for r in records if r["kind"] == kind and r["max_group"] == grouped]
        mean = lambda rs, k: sum(r[k] for r in rs) / len(rs)  # noqa: E731
        summary[kind] = {
            "client_cpu_ms_per_item": {"one_a_task": mean(one, "client_cpu_ms_per_item"),
                                       "grouped": mean(many, "client_cpu_ms_per_item")},
            "client_cpu_ms_per_task_one_a_task": mean(one, "client_cpu_ms_per_task"),
            "wall_s": {"one_a_task": mean(one, "wall_s"), "grouped": mean(many, "wall_s")},
            "identical": len({r["out"] for r in one + many}) == 1,
        }
    result = {"side": args.side, "cpus": os.cpu_count(), "max_group": grouped,
              "summary": summary, "records": records}
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "scale_tasks.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
