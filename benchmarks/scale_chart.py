"""The chart of ``bench_scale.py``: throughput vs workers, memory vs photo and tile size, render."""

from __future__ import annotations

from pathlib import Path

import numpy as np

MODES = (0, 1, 2)
MODE_NAMES = ("serial\n(peer)", "1 worker", "2 workers")


def _throughput(ax, result: dict) -> None:
    """Tile-stage Mpx/s (solid) and Mpx per CPU second (dashed) against the number of workers."""
    tile = result["tile"]
    recs = [r for r in result["records"] if r["tile"] == tile]
    for k, side in enumerate(sorted({r["side"] for r in recs})):
        colour = f"C{k}"
        xs, rate, per_cpu = [], [], []
        for x, workers in enumerate(MODES):
            runs = [r for r in recs if r["side"] == side and r["workers"] == workers]
            if not runs:
                continue
            # Every run as a dot, their mean on the line.
            ax.plot([x] * len(runs), [r["tile_mpx_per_s"] for r in runs], ".", color=colour)
            xs.append(x)
            rate.append(np.mean([r["tile_mpx_per_s"] for r in runs]))
            per_cpu.append(np.mean([1 / r["tile_cpu_s_per_mpx"] for r in runs]))
        ax.plot(xs, rate, "o-", color=colour, label=f"{side}²: Mpx/s (wall)")
        ax.plot(xs, per_cpu, "s--", color=colour, alpha=0.6, label=f"{side}²: Mpx per CPU s")
    loads = sorted(r["load_before"][0] for r in recs)
    ax.set_xticks(range(len(MODES)), MODE_NAMES)
    ax.set_ylabel("tile stages (grid + colour map)")
    ax.set_ylim(bottom=0)
    ax.set_title(f"tiled conversion, tile {tile}: throughput vs workers\n(2 shared cores, load "
                 f"avg at start {loads[0]:.1f}-{loads[-1]:.1f})", fontsize=9)
    ax.legend(fontsize=7)


def _memory_vs_side(ax, result: dict) -> None:
    tile = result["tile"]
    recs = [r for r in result["records"] if r["tile"] == tile]
    for workers in MODES:
        rows = sorted((r["side"], max(r["worker_peak_rss_mib"]) if workers
                       else r["client_peak_rss_mib"]) for r in recs if r["workers"] == workers)
        if rows:
            ax.plot(*zip(*rows, strict=True), "o-", label=(
                "serial process (client and tiles)" if not workers
                else f"each of {workers} worker(s)"))
    rows = sorted((r["side"], r["client_peak_rss_mib"]) for r in recs if r["workers"] == 2)
    ax.plot(*zip(*rows, strict=True), "s--", label="client (2 workers)")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("photo side (pixels)")
    ax.set_ylabel("peak RSS (MiB)")
    ax.set_ylim(bottom=0)
    ax.set_title(f"peak memory per process vs photo size (tile {tile})", fontsize=9)
    ax.legend(fontsize=7)


def _memory_vs_tile(ax, result: dict) -> None:
    small = min(r["side"] for r in result["records"])
    rows = sorted((r["tile"], max(r["worker_peak_rss_mib"])) for r in result["records"]
                  if r["side"] == small and r["workers"] == 2)
    ax.plot(*zip(*rows, strict=True), "o-", label=f"each of 2 workers, {small}² photo")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("tile side (pixels)")
    ax.set_ylabel("peak RSS (MiB)")
    ax.set_ylim(bottom=0)
    ax.set_title("peak memory per worker vs tile size", fontsize=9)
    ax.legend(fontsize=7)


def _render(ax, result: dict) -> None:
    rend = result["renders"]
    sides = [r["side"] for r in rend]
    ax.plot(sides, [r["peak_rss_above_start_mib"] for r in rend], "o-",
            label="render --tiled: peak RSS above start (MiB)")
    ax.plot(sides, [r["file_bytes"] / 2**20 for r in rend], "s--",
            label="its GeoTIFF with overviews (MiB)")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("photo side (pixels)")
    ax.set_title("streamed render: memory vs output size", fontsize=9)
    ax.legend(fontsize=7)


def chart(result: dict, path: Path) -> None:
    """Write the four panels of a ``bench_scale`` result to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ((ax, axm), (axt, axr)) = plt.subplots(2, 2, figsize=(12, 9), dpi=100)
    _throughput(ax, result)
    _memory_vs_side(axm, result)
    _memory_vs_tile(axt, result)
    _render(axr, result)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
