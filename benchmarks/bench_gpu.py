"""GPU renderer benchmark: ms per 1920 x 1080 frame, the shaders against the CPU render, same run.

Run: ``.venv/bin/python benchmarks/bench_gpu.py [--quick] [--frames-only]``
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
  ``LP_NUM_THREADS`` threads, default one per core), every pixel drawn by
  the blend shader;
* ``gpu to numpy``: :meth:`core.gpu.GpuRenderer.render` into a reused
  array: the frame read back, as ``render --gpu`` needs it;
* ``gpu frame from the packed layer``: the same, the grid read from the
  packed layer (``pack(grid)``) by the shaders (``core.gpu.packed``: each
  tile's vertices decoded and cells split on the GPU); its peer is the one
  above. Accuracy: its frames must equal the dense GPU render (max 0).

Accuracy: the largest difference between the GPU and CPU texels of every
frame (linear: must be 0; histogram-preserving: at most 1).

A converted project in its own style (shaped borders + colour map): the
DeepGlobe photo 6399 (2448 x 2448) converted with ``convert``'s defaults,
1920 x 1080 viewports, ``render_cells`` with the project's style against the
shaders (must be equal: max difference 0).

Perspective frames (``core.gpu.GroundView``, the fly-over's renderer): the
bundled ``sample_maps/dubai_marina.jpg`` converted with ``convert``'s
defaults, 1280 x 720 frames from a camera 24 texels up, yaw 30, fov 60, at
pitches 20 to 2.5 degrees; the GPU (anisotropic 16x: shader probes on a
software rasteriser; and trilinear) next to the CPU preview's trilinear, the
parallelogram default and EWA on the project's render, all against the CPU's
supersampled reference (``Method.REFERENCE``): PSNR over ground pixels and
median ms per frame over interleaved rounds.
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
from gpu_chart import chart  # noqa: E402
from terratheme.core.gpu import (  # noqa: E402
    GpuRenderer,
    GpuRenderOptions,
    GroundOptions,
    GroundView,
)
from terratheme.core.packing import pack  # noqa: E402
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells  # noqa: E402
from terratheme.core.render.rules import cell_splits  # noqa: E402

W, H = 1920, 1080
SHARED = HERE.parent.parent / "shared" / "data"
FRAME = (1280, 720)
PITCHES = (20.0, 10.0, 5.0, 2.5)


def converted(path: Path):
    """A photo converted with convert's defaults (shaped borders, colour map)."""
    from terratheme.core.convert.photo import convert_photo
    from terratheme.core.io.images import read_image

    return convert_photo(read_image(path)).project


def style_scenario(project, gpu: GpuRenderer, regions: list, rounds: int) -> dict:
    """1920 x 1080 viewports of a converted project in its style: CPU against the shaders."""
    from terratheme.core.render.project import project_style

    style, cmap = project_style(project), project.colour_map
    textures, grid = project.library.textures, project.grid
    opts = GpuRenderOptions.from_render_options(style)
    buf_cpu, buf_gpu = np.empty((H, W, 3), np.uint8), np.empty((H, W, 3), np.uint8)

    def frame(region):
        gpu.draw(grid, region=region, options=opts, colour_map=cmap)
        gpu.ctx.finish()

    fns = {
        "cpu": lambda r: render_cells(grid, textures, region=r, options=style, colour_map=cmap),
        "cpu (reused buffer)": lambda r: render_cells(grid, textures, region=r, options=style,
                                                      colour_map=cmap, out=buf_cpu),
        "gpu frame": frame,
        "gpu to numpy": lambda r: gpu.render(grid, region=r, options=opts, colour_map=cmap,
                                             out=buf_gpu),
    }
    worst = 0
    for r in regions[:2]:
        cpu = render_cells(grid, textures, region=r, options=style, colour_map=cmap)
        worst = max(worst, int(np.abs(cpu.astype(np.int16) - gpu.render(
            grid, region=r, options=opts, colour_map=cmap)).max()))
    for fn in fns.values():
        fn(regions[0])
    return {"cell": list(grid.cell), "texture": list(grid.texture_size),
            "colour_map_scale": cmap.scale, "boundary": project.metadata.get("render"),
            "mixed_cell_fraction": float((cell_splits(grid.indices) != 0).mean()),
            "max_abs_diff": worst, "linear": measure(fns, regions, rounds)}


def perspective_rows(project, rounds: int, pitches=PITCHES) -> list[dict]:
    """PSNR against the CPU reference and ms per frame, GPU and CPU filters, per pitch."""
    from skimage.metrics import peak_signal_noise_ratio
    from terratheme.core.perspective import (
        Camera,
        FilterOptions,
        Method,
        PreparedTexture,
        camera_mapping,
    )
    from terratheme.core.render.project import render_project

    texture = render_project(project)
    prepared = PreparedTexture(texture)
    cpu = {name: FilterOptions(method=m) for name, m in (
        ("cpu trilinear", Method.TRILINEAR), ("cpu parallelogram", Method.PARALLELOGRAM),
        ("cpu ewa", Method.EWA))}
    views = {"gpu anisotropic 16x": GroundView.from_project(project),
             "gpu trilinear": GroundView.from_project(project, GroundOptions(max_anisotropy=1))}
    rows = []
    for pitch in pitches:
        cam = Camera(height=24.0, pitch=pitch, yaw=30.0, fov=60.0)
        t0 = time.perf_counter()
        ref = prepared.render(cam, FRAME, FilterOptions(method=Method.REFERENCE)).image
        ref_ms = 1e3 * (time.perf_counter() - t0)
        mapping = camera_mapping(cam, FRAME, prepared.texture_size)
        z = mapping.Bz * np.arange(FRAME[1] + 1) + mapping.Cz
        ground = np.repeat(((z[:-1] > 0) & (z[1:] > 0))[:, None], FRAME[0], axis=1)
        fns = {**{k: (lambda v=v, c=cam: v.render(c, FRAME)) for k, v in views.items()},
               **{k: (lambda o=o, c=cam: prepared.render(c, FRAME, o).image)
                  for k, o in cpu.items()}}
        frames = {k: fn() for k, fn in fns.items()}  # warm-up: shaders, numba, families
        times: dict[str, list[float]] = {k: [] for k in fns}
        for rnd in range(rounds):
            for name in (list(fns) if rnd % 2 == 0 else list(reversed(fns))):
                t0 = time.perf_counter()
                frames[name] = fns[name]()
                times[name].append(1e3 * (time.perf_counter() - t0))
        for name, img in frames.items():
            img = img.astype(np.float32) / 255 if img.dtype == np.uint8 else img
            psnr = peak_signal_noise_ratio(ref[ground], img[ground], data_range=1.0)
            rows.append({"pitch": pitch, "method": name, "psnr_db": float(psnr),
                         "ms_per_frame": statistics.median(times[name]),
                         "reference_ms": ref_ms})
            print(f"pitch {pitch:4.1f} {name:20s} {psnr:6.2f} dB "
                  f"{statistics.median(times[name]):8.1f} ms", flush=True)
    for v in views.values():
        v.release()
    return rows


def spots(size: int, count: int) -> list[tuple[int, int, int, int]]:
    """bench_render's viewport positions (the same generator and seed)."""
    rng = np.random.default_rng(0)
    return [(int(rng.integers(0, size - W)), int(rng.integers(0, size - H)), W, H)
            for _ in range(count)]


def contenders(grid, themes, gpu: GpuRenderer, blend: BlendMode) -> dict:
    """name -> callable(region) for one blend mode."""
    cpu_opts = RenderOptions(blend=blend)
    gpu_opts = GpuRenderOptions(blend=blend)
    buf_cpu = np.empty((H, W, 3), np.uint8)
    buf_gpu = np.empty((H, W, 3), np.uint8)
    layer = pack(grid)

    def frame(region, options=gpu_opts, source=grid):
        gpu.draw(source, (N, N), region, options=options)
        gpu.ctx.finish()

    return {
        "cpu": lambda r: render_cells(grid, themes, (N, N), r, options=cpu_opts),
        "cpu (reused buffer)": lambda r: render_cells(grid, themes, (N, N), r,
                                                      options=cpu_opts, out=buf_cpu),
        "gpu frame": frame,
        "gpu to numpy": lambda r: gpu.render(grid, (N, N), r, options=gpu_opts, out=buf_gpu),
        "gpu frame from the packed layer": lambda r: frame(r, gpu_opts, layer),
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
        worst, differ, total, dense_worst = 0, 0, 0, 0
        for r in regions:
            cpu = render_cells(grid, themes, (N, N), r, options=RenderOptions(blend=blend))
            got = gpu.render(grid, (N, N), r, options=GpuRenderOptions(blend=blend))
            d = np.abs(cpu.astype(np.int16) - got)
            worst = max(worst, int(d.max()))
            differ += int((d > 0).sum())
            total += d.size
            packed = gpu.render(pack(grid), (N, N), r, options=GpuRenderOptions(blend=blend))
            dense_worst = max(dense_worst, int(np.abs(packed.astype(np.int16) - got).max()))
        out[blend.value] = {"max_abs_diff": worst, "share_of_values_differing": differ / total,
                            "packed_vs_dense_gpu_max_abs_diff": dense_worst}
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer viewports and rounds")
    ap.add_argument("--frames-only", action="store_true",
                    help="the flat frames only (into the last results: converted and "
                         "perspective rows kept)")
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
    deepglobe = SHARED / "deepglobe" / "images" / "6399_sat.jpg"
    if args.frames_only:
        last = json.loads((HERE / "results" / "gpu.json").read_text())
        res.update(converted=last["converted"], perspective=last["perspective"])
    elif deepglobe.is_file():
        project = converted(deepglobe)
        gpu_style = GpuRenderer(project.library.textures)
        tw, th = project.grid.texture_size
        rng = np.random.default_rng(0)
        views = [(int(rng.integers(0, tw - W)), int(rng.integers(0, th - H)), W, H)
                 for _ in range(len(regions))]
        res["converted"] = {"photo": "DeepGlobe 6399 (2448 x 2448), convert defaults",
                            **style_scenario(project, gpu_style, views, rounds)}
        print("converted", json.dumps(res["converted"]["linear"]["median_ms"]), flush=True)
        gpu_style.release()
    if not args.frames_only:
        sample = converted(HERE.parent / "sample_maps" / "dubai_marina.jpg")
        res["perspective"] = {
            "project": "sample_maps/dubai_marina.jpg, convert defaults", "frame": list(FRAME),
            "camera": "height 24 texels, yaw 30, fov 60",
            "texture": list(sample.grid.texture_size),
            "rows": perspective_rows(sample, 1 if args.quick else 3,
                                     PITCHES[::2] if args.quick else PITCHES)}
    res["load_average_end"] = os.getloadavg()[0]
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / "gpu.json").write_text(json.dumps(res, indent=1) + "\n")
    chart(res, out / "gpu.png")
    print(json.dumps({k: {b: v[b]["cpu_over_contender_median"] for b in ("linear", "histogram")}
                      for k, v in res["scenarios"].items()}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
