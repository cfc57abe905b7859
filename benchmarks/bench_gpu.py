"""GPU renderer benchmark: ms per 1920 x 1080 frame, the shaders against the CPU render, same run.

Run: ``.venv/bin/python benchmarks/bench_gpu.py [--quick]``
Writes ``benchmarks/results/gpu.json`` and ``gpu.png``.

Map: the ESA WorldCover 2020 crop of ``bench_render.py`` (CC BY 4.0, "© ESA
WorldCover project / contains modified Copernicus Sentinel data (2020)")
reduced to a 513 x 513 vertex grid, cell 16 x 16 (an 8192 x 8192 texture),
shipped themes; and the same grid with random vertices (almost every cell
blends three themes), the worst case.

Each round renders the same 1920 x 1080 viewports (bench_render's spots)
with every contender back to back, so machine load hits them alike:

* ``cpu``: :func:`core.render.render_cells` with the region (numba, 2
  threads), into a fresh array as the viewport figure of bench_render, and
  into a reused buffer;
* ``gpu frame``: :meth:`core.gpu.GpuRenderer.draw` + ``glFinish``: the
  frame in the framebuffer, where a display would show it (Mesa llvmpipe,
  ``LP_NUM_THREADS`` threads, default one per core); runs of uniform cells
  are image copies, blended cells drawn by the blend shader;
* ``gpu to numpy``: :meth:`core.gpu.GpuRenderer.render` into a reused
  array: the frame read back, as ``render --gpu`` needs it;
* ``gpu frame, uniform cells by copy shader``: runs of uniform cells drawn
  with ``tt_copy.frag.glsl`` instead of copied (a driver without OpenGL 4.3);
* ``gpu blend shader alone``: every pixel by ``tt_terrain.frag.glsl``, as an
  engine using that shader alone would draw it (no uniform-cell special case).

Accuracy: the largest difference between the GPU and CPU texels of every
frame (linear: must be 0; histogram-preserving: at most 1).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from bench_render import N, esa_grid  # noqa: E402

from core.gpu import GpuRenderer, GpuRenderOptions, UniformCells  # noqa: E402
from core.render.renderer import BlendMode, RenderOptions, render_cells  # noqa: E402
from core.render.rules import cell_splits  # noqa: E402

W, H = 1920, 1080


def spots(size: int, count: int) -> list[tuple[int, int, int, int]]:
    """bench_render's viewport positions (the same generator and seed)."""
    rng = np.random.default_rng(0)
    return [(int(rng.integers(0, size - W)), int(rng.integers(0, size - H)), W, H)
            for _ in range(count)]


def contenders(grid, themes, gpu: GpuRenderer, blend: BlendMode) -> dict:
    """name -> callable(region) for one blend mode."""
    cpu_opts = RenderOptions(blend=blend)
    gpu_opts = GpuRenderOptions(blend=blend)
    shader = GpuRenderOptions(blend=blend, uniform_cells=UniformCells.SHADER)
    alone = GpuRenderOptions(blend=blend, uniform_cells=UniformCells.BLEND)
    buf_cpu = np.empty((H, W, 3), np.uint8)
    buf_gpu = np.empty((H, W, 3), np.uint8)

    def frame(region, options=gpu_opts):
        gpu.draw(grid, (N, N), region, options=options)
        gpu.ctx.finish()

    return {
        "cpu": lambda r: render_cells(grid, themes, (N, N), r, options=cpu_opts),
        "cpu (reused buffer)": lambda r: render_cells(grid, themes, (N, N), r,
                                                      options=cpu_opts, out=buf_cpu),
        "gpu frame": frame,
        "gpu to numpy": lambda r: gpu.render(grid, (N, N), r, options=gpu_opts, out=buf_gpu),
        "gpu frame, uniform cells by copy shader": lambda r: frame(r, shader),
        "gpu blend shader alone": lambda r: frame(r, alone),
    }


def measure(fns: dict, regions: list, rounds: int) -> dict:
    """Interleaved wall times (ms): every round runs every contender on every region."""
    wall = {k: [] for k in fns}
    cpu_time = {k: [] for k in fns}
    ratios = {k: [] for k in fns if k != "cpu"}
    for rnd in range(rounds):
        names = list(fns) if rnd % 2 == 0 else list(reversed(fns))
        for region in regions:
            got = {}
            for name in names:
                t0, c0 = time.perf_counter(), time.process_time()
                fns[name](region)
                got[name] = 1e3 * (time.perf_counter() - t0)
                wall[name].append(got[name])
                cpu_time[name].append(1e3 * (time.process_time() - c0))
            for name in ratios:
                ratios[name].append(got["cpu"] / got[name])
    return {
        "median_ms": {k: statistics.median(v) for k, v in wall.items()},
        "p10_ms": {k: float(np.percentile(v, 10)) for k, v in wall.items()},
        "p90_ms": {k: float(np.percentile(v, 90)) for k, v in wall.items()},
        "median_process_cpu_ms": {k: statistics.median(v) for k, v in cpu_time.items()},
        "cpu_over_contender_median": {k: statistics.median(v) for k, v in ratios.items()},
        "cpu_over_contender_p10_p90": {k: [float(np.percentile(v, 10)),
                                           float(np.percentile(v, 90))]
                                       for k, v in ratios.items()},
    }


def accuracy(grid, themes, gpu: GpuRenderer, regions: list) -> dict:
    """Largest |GPU - CPU| over the frames, per blend, and the share of texels differing."""
    out = {}
    for blend in (BlendMode.LINEAR, BlendMode.HISTOGRAM):
        worst, differ, total = 0, 0, 0
        for r in regions:
            cpu = render_cells(grid, themes, (N, N), r, options=RenderOptions(blend=blend))
            for fill in (UniformCells.COPY, UniformCells.SHADER, UniformCells.BLEND):
                got = gpu.render(grid, (N, N), r, options=GpuRenderOptions(
                    blend=blend, uniform_cells=fill))
                d = np.abs(cpu.astype(np.int16) - got)
                worst = max(worst, int(d.max()))
                differ += int((d > 0).sum())
                total += d.size
        out[blend.value] = {"max_abs_diff": worst, "share_of_values_differing": differ / total}
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer viewports and rounds")
    args = ap.parse_args()
    grid, themes, names = esa_grid(513)
    size = (grid.shape[1] - 1) * N
    worst = np.random.default_rng(1).integers(0, len(themes), grid.shape).astype(np.uint8)
    gpu = GpuRenderer(themes)
    regions = spots(size, 4 if args.quick else 8)
    rounds = 3 if args.quick else 7
    res: dict = {
        "map": "ESA WorldCover 2020 crop -> 513x513 vertices", "cell": [N, N],
        "frame": [W, H], "themes": names, "rounds": rounds, "viewports": regions,
        "gl_renderer": gpu.ctx.info["GL_RENDERER"], "gl_version": gpu.ctx.info["GL_VERSION"],
        "lp_num_threads": os.environ.get("LP_NUM_THREADS", f"default ({os.cpu_count()})"),
        "cpu_count": os.cpu_count(), "load_average_start": os.getloadavg()[0],
        "scenarios": {},
    }
    for label, g in (("esa", grid), ("random vertices (worst case)", worst)):
        splits = cell_splits(g)
        scen = {"mixed_cell_fraction": float((splits != 0).mean()),
                "accuracy": accuracy(g, themes, gpu, regions[:2])}
        for blend in (BlendMode.LINEAR, BlendMode.HISTOGRAM):
            fns = contenders(g, themes, gpu, blend)
            if blend is BlendMode.HISTOGRAM:
                fns = {k: fns[k] for k in ("cpu", "gpu frame", "gpu to numpy")}
            for fn in fns.values():
                fn(regions[0])  # warm up: shader compilation, numba cache, theme packs
            scen[blend.value] = measure(fns, regions, rounds)
            print(label, blend.value, json.dumps(scen[blend.value]["median_ms"]), flush=True)
        res["scenarios"][label] = scen
    res["load_average_end"] = os.getloadavg()[0]
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / "gpu.json").write_text(json.dumps(res, indent=1) + "\n")
    chart(res, out / "gpu.png")
    print(json.dumps({k: {b: v[b]["cpu_over_contender_median"] for b in ("linear", "histogram")}
                      for k, v in res["scenarios"].items()}, indent=1))
    return 0


def chart(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scen = res["scenarios"]
    fig, axes = plt.subplots(1, 2 * len(scen), figsize=(7 * len(scen) * 2 / 1.6, 5))
    colours = {"cpu": "C3", "cpu (reused buffer)": "C1", "gpu frame": "C0",
               "gpu to numpy": "C2", "gpu frame, uniform cells by copy shader": "C9",
               "gpu blend shader alone": "C7"}
    i = 0
    for label, sc in scen.items():
        for blend in ("linear", "histogram"):
            ax = axes[i]
            i += 1
            m = sc[blend]
            names = list(m["median_ms"])
            med = [m["median_ms"][k] for k in names]
            lo = [m["median_ms"][k] - m["p10_ms"][k] for k in names]
            hi = [m["p90_ms"][k] - m["median_ms"][k] for k in names]
            ax.bar(range(len(names)), med, yerr=[lo, hi], capsize=3,
                   color=[colours[k] for k in names])
            ax.set_xticks(range(len(names)), names, rotation=25, ha="right", fontsize=8)
            for j, v in enumerate(med):
                ax.text(j, v, f"{v:.1f}", ha="center", va="bottom", fontsize=8)
            acc = sc["accuracy"][blend]["max_abs_diff"]
            ratio = m["cpu_over_contender_median"].get("gpu frame", float("nan"))
            ax.set_title(f"{label}, {blend}\n(map cells blended {sc['mixed_cell_fraction']:.1%}; "
                         f"cpu / gpu frame {ratio:.2f}x; max |gpu-cpu| {acc})", fontsize=9)
            ax.set_ylabel("ms per 1920 x 1080 frame (median, p10-p90)")
    fig.suptitle(f"GPU renderer on {res['gl_renderer']} vs CPU render_cells, same run, "
                 f"{res['cpu_count']} cores (load {res['load_average_start']:.1f} at start)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
