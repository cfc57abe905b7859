"""How well each make_tileable method hides the tiling, on real photo patches.

Run: ``.venv/bin/python benchmarks/bench_tileable.py`` (about a minute on 2 busy cores).
Writes ``benchmarks/results/tileable.json`` and ``tileable.png``.

Patches: 32 seeded random square windows of the Dubai photos in
``../shared/data/dubai`` (8 each of 32, 64, 128 and 256 texels). Every
method below runs on the same patches in the same run; for each we report
the mean (and worst) of

* ``seam``    -- :func:`core.themes.tileable.seam_score` (wrap-edge step / interior
  step; 1 = like the interior, the pass mark is 1.5);
* ``repeat``  -- :func:`core.themes.quality.repeat_score` (self-similarity of
  the detail at a non-trivial shift: ghosts and copied strips; the raw
  patch's own level is shown as ``raw``);
* ``lowfreq`` -- :func:`core.themes.quality.lowfreq_score` (share of the
  contrast in waves of <= 2 periods per tile: banding in a tiling);
* ``detail``  -- the std of the luminance minus its sigma-2 blur, over the
  raw patch's (fine texture kept: 1 = all of it);
* ``time``    -- per patch, as a ratio to the default method.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from terratheme.core.io.images import read_image  # noqa: E402
from terratheme.core.themes.quality import lowfreq_score, repeat_score  # noqa: E402
from terratheme.core.themes.tileable import (  # noqa: E402
    TileableOptions,
    make_tileable,
    seam_score,
)
from tileable_peers import make_tileable_peer  # noqa: E402

DEFAULT = TileableOptions()


def _core(**kw):
    return lambda patch: make_tileable(patch, replace(DEFAULT, **kw))


def _peer(method, **kw):
    return lambda patch: make_tileable_peer(patch, method, **kw)


#: name -> patch -> tile; the cut and cross-fade wraps and flattening by division are peers
METHODS = {
    "crossfade (old)": _peer("crossfade", flatten=0.0, tiles_already=0),
    "crossfade+flat": _peer("crossfade"),
    "cut": _peer("cut", flatten=0.0),
    "cut+flat": _peer("cut"),
    "cut+flat ov1/16": _peer("cut", overlap=1 / 16),
    "periodic": _core(flatten=0.0),
    "periodic+flat1/32": _core(flatten=1 / 32),
    "periodic+flat1/24": _core(flatten=1 / 24),
    "periodic+flat1/16": _core(flatten=1 / 16),
    "periodic+flat1/8": _core(flatten=1 / 8),
    "periodic+flat1/16 div": _peer("periodic", flatten=1 / 16, divide=True),
}
SIZES = (32, 64, 128, 256)
PER_SIZE = 8


def _detail(img: np.ndarray) -> float:
    lum = img.astype(np.float64) @ np.array([0.299, 0.587, 0.114])
    return float((lum - gaussian_filter(lum, 2.0, mode="mirror")).std())


def patches(dubai: Path) -> list[tuple[str, np.ndarray]]:
    """Seeded random square windows of the Dubai photos."""
    rng = np.random.default_rng(7)
    files = sorted((dubai / "images").glob("*.jpg"))
    out = []
    for size in SIZES:
        for _ in range(PER_SIZE):
            path = files[rng.integers(len(files))]
            photo = read_image(path, dtype=np.uint8)[..., :3]
            y = int(rng.integers(photo.shape[0] - size))
            x = int(rng.integers(photo.shape[1] - size))
            out.append((f"{path.name} x={x} y={y} {size}", photo[y : y + size, x : x + size]))
    return out


def run() -> dict:
    dubai = REPO.parent / "shared" / "data" / "dubai"
    if not (dubai / "images").is_dir():
        raise SystemExit(f"{dubai}: Dubai photos not found")
    items = patches(dubai)
    raw = [(repeat_score(p), lowfreq_score(p), seam_score(p)) for _, p in items]
    rows = {}
    default_time = None
    for name, method in [("default", make_tileable), *METHODS.items()]:
        scores, t_total = [], 0.0
        for (_, patch), _r in zip(items, raw, strict=True):
            t0 = time.perf_counter()
            tile = method(patch)
            t_total += time.perf_counter() - t0
            scores.append(
                (seam_score(tile), repeat_score(tile), lowfreq_score(tile),
                 _detail(tile) / max(_detail(patch), 1e-9))
            )
        a = np.array(scores)
        if name == "default":
            default_time = t_total
            continue
        rows[name] = {
            "seam_mean": float(a[:, 0].mean()), "seam_max": float(a[:, 0].max()),
            "repeat_mean": float(a[:, 1].mean()), "repeat_max": float(a[:, 1].max()),
            "lowfreq_mean": float(a[:, 2].mean()), "lowfreq_max": float(a[:, 2].max()),
            "detail_mean": float(a[:, 3].mean()), "detail_min": float(a[:, 3].min()),
            "ms_per_patch": 1e3 * t_total / len(items),
            "time_ratio_to_default": t_total / default_time,
        }
    r = np.array(raw)
    return {
        "patches": [n for n, _ in items],
        "default": {"method": "periodic", "flatten": DEFAULT.flatten},
        "raw": {"seam_mean": float(r[:, 2].mean()), "repeat_mean": float(r[:, 0].mean()),
                "lowfreq_mean": float(r[:, 1].mean())},
        "methods": rows,
    }


def chart(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(result["methods"])
    fig, axes = plt.subplots(1, 4, figsize=(17, 5), sharey=True)
    y = np.arange(len(names))
    for ax, key, title, ref in (
        (axes[0], "seam", "seam score (pass < 1.5)", result["raw"]["seam_mean"]),
        (axes[1], "repeat", "repeat score (ghosts / copies)", result["raw"]["repeat_mean"]),
        (axes[2], "lowfreq", "low-frequency share (banding)", result["raw"]["lowfreq_mean"]),
        (axes[3], "detail", "fine detail kept", 1.0),
    ):
        mean = [result["methods"][n][f"{key}_mean"] for n in names]
        worst = [result["methods"][n][f"{key}_{'min' if key == 'detail' else 'max'}"]
                 for n in names]
        ax.barh(y, mean, color="tab:blue", label="mean")
        ax.plot(worst, y, "k|", markersize=12, label="worst")
        ax.axvline(ref, color="tab:red", ls="--", label="raw patch" if key != "detail" else "raw")
        ax.set_title(title)
        ax.legend(fontsize=7)
    axes[0].set_yticks(y, names)
    axes[0].invert_yaxis()
    default = result["default"]
    fig.suptitle(f"make_tileable on {len(result['patches'])} Dubai patches (32-256 px); "
                 f"default: {default['method']}, flatten {default['flatten']:.4g}")
    fig.tight_layout()
    fig.savefig(path, dpi=80)


def main() -> int:
    out = REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    result = run()
    (out / "tileable.json").write_text(json.dumps(result, indent=1) + "\n")
    chart(result, out / "tileable.png")
    for name, row in result["methods"].items():
        print(f"{name:24s} seam {row['seam_mean']:.2f}/{row['seam_max']:.2f} "
              f"repeat {row['repeat_mean']:.3f}/{row['repeat_max']:.3f} "
              f"lowfreq {row['lowfreq_mean']:.3f}/{row['lowfreq_max']:.3f} "
              f"detail {row['detail_mean']:.2f}/{row['detail_min']:.2f} "
              f"time x{row['time_ratio_to_default']:.2f}")
    print("raw", result["raw"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
