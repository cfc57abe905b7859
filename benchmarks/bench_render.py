"""Renderer benchmark: speed against two peers in the same run, and storage against the photo.

Run: ``.venv/bin/python benchmarks/bench_render.py [--quick]``
Writes ``benchmarks/results/render.json``, ``render.png`` (charts) and
``render_border.png`` (the four renders side by side at a theme border).

Map: the ESA WorldCover 2020 crop (CC BY 4.0, "© ESA WorldCover project /
contains modified Copernicus Sentinel data (2020)") reduced to a 513 x 513
vertex grid (nearest), cell 16 x 16 -> an 8192 x 8192 texture, shipped themes.

Contenders, same run, same grid and themes:

* ``terratheme``: ``core.render.renderer.render_cells`` (numba kernel, 2 threads),
  linear and histogram-preserving blend;
* ``numpy vectorised``: the same algorithm as whole-band numpy gathers
  (shows what numba buys);
* ``per-cell loop``: a straightforward loop over cells of the paper's
  algorithm, numpy inside each cell (DESIGN.md §1 as written);
* ``opencv splatmap``: one-hot vertex maps upsampled bilinearly with
  ``cv2.resize``, then a weighted sum of the tiled themes (the engine way).
"""

from __future__ import annotations

import argparse
import io
import json
import statistics
import sys
import tempfile
import timeit
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))

from terratheme.core.io.images import read_image, write_image  # noqa: E402
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells  # noqa: E402
from terratheme.core.render.rules import cell_splits, corner_weights  # noqa: E402
from terratheme.core.themes.library import shipped_theme_library  # noqa: E402

SHARED = REPO.parent / "shared" / "data"
ESA = {10: "forest", 20: "grass", 30: "grass", 40: "crop field", 50: "town", 60: "sand",
       80: "water", 90: "grass", 95: "forest", 0: "water"}
N = 16


def esa_grid(size: int) -> tuple[np.ndarray, list[np.ndarray], list[str]]:
    """(size, size) vertex grid from ESA WorldCover plus the themes it uses."""
    path = next((SHARED / "maps" / "esa_worldcover").glob("*.png"))
    cls = read_image(path)[..., 0]
    small = cv2.resize(cls, (size, size), interpolation=cv2.INTER_NEAREST)
    names = sorted(set(ESA.values()))
    lut = np.zeros(256, np.uint8)
    for c, name in ESA.items():
        lut[c] = names.index(name)
    lib = shipped_theme_library().select(names)
    return lut[small], lib.textures, names


def best_time(fn, repeat: int) -> float:
    """Smallest wall time of ``repeat`` calls, seconds."""
    return min(timeit.repeat(fn, number=1, repeat=repeat))


# ---------------------------------------------------------------- peers


def numpy_vectorised(grid, themes, n, m, region):
    """The same exact algorithm with numpy gathers over 256-row bands (no numba)."""
    rx, ry, rw, rh = region
    stack = np.stack(themes)  # all shipped themes are 256 x 256
    th, tw = stack.shape[1:3]
    splits = cell_splits(grid)
    out = np.empty((rh, rw, 3), np.uint8)
    xs = np.arange(rx, rx + rw)
    cx = xs // n
    xi = ((xs - cx * n) * m)[None, :]
    for r0 in range(0, rh, 256):
        ys = np.arange(ry + r0, ry + min(rh, r0 + 256))
        cy = ys // m
        yi = ((ys - cy * m) * n)[:, None]
        ws = corner_weights(splits[cy[:, None], cx[None, :]], xi, yi, n * m)
        acc = np.zeros((len(ys), rw, 3), np.int32)
        for (dr, dc), w in zip(((0, 0), (0, 1), (1, 0), (1, 1)), ws, strict=True):
            k = grid[cy[:, None] + dr, cx[None, :] + dc]
            acc += w[..., None] * stack[k, (ys % th)[:, None], (xs % tw)[None, :]]
        out[r0 : r0 + len(ys)] = (2 * acc + n * m) // (2 * n * m)
    return out


def per_cell_loop(grid, themes, n, m, region):
    """The paper's algorithm as printed: a loop over cells, one numpy block per cell."""
    rx, ry, rw, rh = region
    out = np.empty((rh, rw, 3), np.uint8)
    x = (np.arange(n) / n)[None, :, None]
    y = (np.arange(m) / m)[:, None, None]
    for j in range(ry // m, (ry + rh) // m):
        for i in range(rx // n, (rx + rw) // n):
            a, b, c, d = grid[j, i], grid[j, i + 1], grid[j + 1, i], grid[j + 1, i + 1]
            ys = np.arange(j * m, j * m + m)
            xs = np.arange(i * n, i * n + n)

            def T(k, ys=ys, xs=xs):
                t = themes[k]
                return t[(ys % t.shape[0])[:, None], (xs % t.shape[1])[None, :]].astype(np.float32)

            if a == b == c == d:
                blk = T(a)
            elif a == d:
                blk = np.where(x <= y, T(c) * (y - x) + T(a) * (1 - y) + T(d) * x,
                               T(b) * (x - y) + T(a) * (1 - x) + T(d) * y)
            else:
                blk = np.where(x + y <= 1, T(a) * (1 - x - y) + T(b) * x + T(c) * y,
                               T(d) * (x + y - 1) + T(b) * (1 - y) + T(c) * (1 - x))
            out[j * m - ry : j * m - ry + m, i * n - rx : i * n - rx + n] = blk + 0.5
    return out


def splatmap(grid, themes, n, m, region, band=128):
    """Engine-style splat: bilinear one-hot weight maps (cv2.resize) and a weighted sum.

    Done reasonably well: row bands, only the vertices under the band are
    upsampled, themes absent from a band are skipped, OpenCV arithmetic.
    """
    rx, ry, rw, rh = region
    out = np.empty((rh, rw, 3), np.uint8)
    tiled = {}
    for r0 in range(0, rh, band):
        y0, y1 = ry + r0, ry + min(rh, r0 + band)
        # Vertex block under the band, one vertex of margin for the bilinear taps.
        vy0, vy1 = max(y0 // m - 1, 0), min((y1 - 1) // m + 3, grid.shape[0])
        vx0, vx1 = max(rx // n - 1, 0), min((rx + rw - 1) // n + 3, grid.shape[1])
        block = grid[vy0:vy1, vx0:vx1]
        acc = np.zeros((y1 - y0, rw, 3), np.float32)
        for k in np.unique(block):
            onehot = (block == k).astype(np.float32)
            w = cv2.resize(onehot, (block.shape[1] * n, block.shape[0] * m),
                           interpolation=cv2.INTER_LINEAR)
            w = w[y0 - vy0 * m : y1 - vy0 * m, rx - vx0 * n : rx - vx0 * n + rw]
            if k not in tiled:
                t = themes[k]
                tiled[k] = np.tile(t, (1, -(-(rx + rw) // t.shape[1]) + 1, 1))
            t = tiled[k]
            rows = t[np.arange(y0, y1) % t.shape[0], rx : rx + rw]
            acc += cv2.multiply(cv2.merge([w, w, w]), rows, dtype=cv2.CV_32F)
        out[r0 : r0 + (y1 - y0)] = cv2.convertScaleAbs(acc)
    return out


# ---------------------------------------------------------------- storage


def encoded_size(img: np.ndarray, suffix: str) -> int:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"x{suffix}"
        write_image(p, img)
        return p.stat().st_size


def storage(themes_bytes: dict[str, int]) -> dict:
    """Bytes of grid (PNG) + themes against the Dubai photo as PNG and JPEG, per cell size."""
    photo_path = max((SHARED / "dubai" / "images").glob("*.jpg"), key=lambda p: p.stat().st_size)
    photo = read_image(photo_path, dtype=np.uint8)[..., :3]
    mask = read_image(SHARED / "dubai" / "masks" / (photo_path.stem + ".png"))[..., 0]
    used = {1: "town", 2: "sand", 3: "road", 4: "grass", 5: "water", 6: "rock"}
    theme_total = sum(themes_bytes[used[c]] for c in np.unique(mask) if c in used)
    h, w = mask.shape
    rows = []
    for c in (4, 8, 16, 32, 64):
        g = cv2.resize(mask, (w // c + 1, h // c + 1), interpolation=cv2.INTER_NEAREST)
        gb = encoded_size(g[:, :, None], ".png")
        rows.append({"cell": c, "grid_bytes": gb, "grid_plus_themes": gb + theme_total})
    return {
        "photo": photo_path.name, "size": [w, h],
        "photo_png": encoded_size(photo, ".png"), "photo_jpeg_q90": _jpeg(photo, 90),
        "themes_bytes": theme_total, "cells": rows,
    }


def _jpeg(img: np.ndarray, q: int) -> int:
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(img[..., ::-1]),
                           [cv2.IMWRITE_JPEG_QUALITY, q])
    return len(io.BytesIO(buf.tobytes()).getvalue())


# ---------------------------------------------------------------- main


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="smaller peer regions, fewer repeats")
    args = ap.parse_args()
    repeat = 2 if args.quick else 3
    grid, themes, names = esa_grid(513)
    size = (grid.shape[1] - 1) * N
    full = (0, 0, size, size)
    mixed = float((cell_splits(grid) != 0).mean())
    res: dict = {"map": "ESA WorldCover 2020 crop -> 513x513 vertices", "cell": [N, N],
                 "texture": [size, size], "themes": names, "mixed_cell_fraction": mixed}
    # Warm up (numba cache load, theme packing).
    render_cells(grid, themes, (N, N), (0, 0, 64, 64))
    render_cells(grid, themes, (N, N), (0, 0, 64, 64),
                 options=RenderOptions(blend=BlendMode.HISTOGRAM))
    mpx = size * size / 1e6
    t_ours = best_time(lambda: render_cells(grid, themes, (N, N)), repeat)
    t_ours1 = best_time(lambda: render_cells(grid, themes, (N, N),
                                             options=RenderOptions(threads=1)), repeat)
    # Into a reused buffer: no page faults of a fresh 200 MB allocation.
    buf = np.empty((size, size, 3), np.uint8)
    t_ours_buf = best_time(lambda: render_cells(grid, themes, (N, N), out=buf), repeat)
    # Worst case: random vertices, (almost) every cell blends three themes.
    worst = np.random.default_rng(1).integers(0, len(themes), grid.shape).astype(np.uint8)
    res["worst_case_mixed_cell_fraction"] = float((cell_splits(worst) != 0).mean())
    t_worst = best_time(lambda: render_cells(grid=worst, themes=themes, cell=(N, N), out=buf),
                        repeat)
    t_splat_worst = best_time(lambda: splatmap(worst, themes, N, N, (0, 0, size, 2048)), 1)
    buf = None  # free the 200 MB buffer
    # Peers: the splatmap on the full texture; the slow ones on a band, reported per Mpx.
    t_splat = best_time(lambda: splatmap(grid, themes, N, N, full), 1 if args.quick else 2)
    band = (0, 0, size, 1024 if args.quick else 2048)
    band_mpx = band[2] * band[3] / 1e6
    t_np = best_time(lambda: numpy_vectorised(grid, themes, N, N, band), 1)
    loop_band = (0, 0, size, 256 if args.quick else 1024)
    t_loop = best_time(lambda: per_cell_loop(grid, themes, N, N, loop_band), 1)
    loop_mpx = loop_band[2] * loop_band[3] / 1e6
    hist_band = (0, 0, size, 1024)
    t_hist = best_time(lambda: render_cells(grid, themes, (N, N), hist_band,
                                            options=RenderOptions(blend=BlendMode.HISTOGRAM)), 1)
    speed = {
        "terratheme linear (2 threads)": mpx / t_ours,
        "terratheme linear (1 thread)": mpx / t_ours1,
        "terratheme linear (2 threads, reused buffer)": mpx / t_ours_buf,
        "terratheme histogram (2 threads)": size * 1024 / 1e6 / t_hist,
        "numpy vectorised (same algorithm)": band_mpx / t_np,
        "per-cell loop (paper)": loop_mpx / t_loop,
        "opencv splatmap": mpx / t_splat,
    }
    res["full_render_mpx_per_s"] = speed
    res["worst_case_mpx_per_s"] = {
        "terratheme linear (2 threads, reused buffer)": mpx / t_worst,
        "opencv splatmap": size * 2048 / 1e6 / t_splat_worst,
    }
    res["full_render_seconds_terratheme"] = t_ours
    res["ratio_vs_splatmap"] = speed["terratheme linear (2 threads)"] / speed["opencv splatmap"]
    res["ratio_vs_per_cell_loop"] = (speed["terratheme linear (2 threads)"]
                                     / speed["per-cell loop (paper)"])
    res["ratio_vs_numpy_vectorised"] = (speed["terratheme linear (2 threads)"]
                                        / speed["numpy vectorised (same algorithm)"])
    # Viewports: 1920 x 1080 windows at several places, median ms.
    rng = np.random.default_rng(0)
    spots = [(int(rng.integers(0, size - 1920)), int(rng.integers(0, size - 1080)))
             for _ in range(8 if not args.quick else 4)]
    vp = {}
    for label, opts in (("linear", RenderOptions()),
                        ("histogram", RenderOptions(blend=BlendMode.HISTOGRAM))):
        ts = [best_time(lambda x=x, y=y, o=opts: render_cells(grid, themes, (N, N),
                                                              (x, y, 1920, 1080), options=o), 1)
              for x, y in spots]
        vp[label] = 1000 * statistics.median(ts)
    ts = [best_time(lambda x=x, y=y: splatmap(grid, themes, N, N, (x, y, 1920, 1080)), 1)
          for x, y in spots[:3]]
    vp["opencv splatmap"] = 1000 * statistics.median(ts)
    res["viewport_1920x1080_ms"] = vp
    # Exactness: the vectorised peer implements the same rule, so it must agree bit for bit.
    ours_band = render_cells(grid, themes, (N, N), (0, 0, size, 256))
    res["numpy_peer_identical"] = bool(np.array_equal(
        ours_band, numpy_vectorised(grid, themes, N, N, (0, 0, size, 256))))
    # Storage.
    lib = shipped_theme_library()
    themes_bytes = {t.name: (REPO / "themes" / t.source.split("/")[-1]).stat().st_size
                    for t in lib}
    res["storage"] = storage(themes_bytes)
    big = render_cells(grid, themes, (N, N))
    res["storage_8192"] = {
        "grid_png": encoded_size(grid[:, :, None], ".png"),
        "themes": sum(themes_bytes[nm] for nm in names),
        "render_png": encoded_size(big, ".png"),
        "render_jpeg_q90": _jpeg(big, 90),
    }
    del big
    border_picture(grid, themes, res)
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / "render.json").write_text(json.dumps(res, indent=1) + "\n")
    chart(res, out / "render.png")
    print(json.dumps(res, indent=1))
    return 0


def border_picture(grid, themes, res) -> None:
    """Save the four renders of one 192 x 192 window at a theme border side by side."""
    splits = cell_splits(grid)
    # The window whose 12 x 12 cells hold the most distinct themes and mixed cells.
    best, where = -1.0, (0, 0)
    for j in range(0, grid.shape[0] - 13, 6):
        for i in range(0, grid.shape[1] - 13, 6):
            score = len(np.unique(grid[j : j + 13, i : i + 13])) + (splits[j:j + 12, i:i + 12]
                                                                   != 0).mean()
            if score > best:
                best, where = score, (i * N, j * N)
    x, y = where
    reg = (x, y, 192, 192)
    pics = {
        "terratheme linear": render_cells(grid, themes, (N, N), reg),
        "terratheme histogram": render_cells(grid, themes, (N, N), reg,
                                             options=RenderOptions(blend=BlendMode.HISTOGRAM)),
        "per-cell loop (paper)": per_cell_loop(grid, themes, N, N, reg),
        "opencv splatmap": splatmap(grid, themes, N, N, reg),
    }
    res["border_window"] = list(reg)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(16, 4.6))
    for ax, (label, img) in zip(axes, pics.items(), strict=True):
        ax.imshow(cv2.resize(img, (384, 384), interpolation=cv2.INTER_NEAREST))
        ax.set_title(label)
        ax.axis("off")
    fig.suptitle(f"theme border, window x={x} y={y} 192x192 texels (shown 2x), cell {N}x{N}")
    fig.tight_layout()
    fig.savefig(HERE / "results" / "render_border.png", dpi=60)
    plt.close(fig)


def chart(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(22, 5))
    sp = res["full_render_mpx_per_s"]
    ax = axes[0]
    ax.barh(list(sp), list(sp.values()), color=["C0", "C0", "C0", "C2", "C7", "C7", "C3"])
    ax.axvline(50, color="k", ls="--", lw=0.8, label="goal 50 Mpx/s")
    ax.set_xscale("log")
    ax.set_xlabel("Mpx/s (8192 x 8192 full render, log scale)")
    ax.set_title(f"speed, same run ({res['ratio_vs_splatmap']:.1f}x splatmap)")
    for i, v in enumerate(sp.values()):
        ax.text(v, i, f" {v:.1f}", va="center")
    ax.legend(loc="lower right")
    ax = axes[1]
    vp = res["viewport_1920x1080_ms"]
    ax.bar(list(vp), list(vp.values()), color=["C0", "C2", "C3"])
    ax.axhline(50, color="k", ls="--", lw=0.8, label="goal 50 ms")
    ax.set_ylabel("ms")
    ax.set_title("1920 x 1080 viewport (median)")
    for i, v in enumerate(vp.values()):
        ax.text(i, v, f"{v:.0f}", ha="center", va="bottom")
    ax.legend()
    ax = axes[2]
    st = res["storage"]
    cells = [r["cell"] for r in st["cells"]]
    ax.plot(cells, [r["grid_bytes"] for r in st["cells"]], "o-", label="grid (PNG)")
    ax.plot(cells, [r["grid_plus_themes"] for r in st["cells"]], "o-",
            label="grid + themes used")
    ax.axhline(st["photo_png"], color="C3", ls="--", label="photo as PNG")
    ax.axhline(st["photo_jpeg_q90"], color="C4", ls="--", label="photo as JPEG q90")
    ax.set_xscale("log", base=2)
    ax.set(yscale="log", xlabel="cell size N = M (texels)", ylabel="bytes",
           title=f"storage: {st['photo']} ({st['size'][0]}x{st['size'][1]})")
    ax.legend(fontsize=8)
    ax = axes[3]
    s8 = res["storage_8192"]
    labels = ["grid (PNG)", "themes (PNG)", "grid + themes", "render as PNG", "render as JPEG q90"]
    vals = [s8["grid_png"], s8["themes"], s8["grid_png"] + s8["themes"], s8["render_png"],
            s8["render_jpeg_q90"]]
    ax.bar(labels, vals, color=["C0", "C1", "C2", "C3", "C4"])
    ax.set_yscale("log")
    ax.set_ylabel("bytes")
    ax.set_title(f"8192 x 8192 texture, cell {res['cell'][0]}: "
                 f"{s8['render_png'] / (s8['grid_png'] + s8['themes']):.0f}x smaller than PNG")
    ax.tick_params(axis="x", labelrotation=20)
    for i, v in enumerate(vals):
        ax.text(i, v, f"{v / 1e3:,.0f} kB", ha="center", va="bottom", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
