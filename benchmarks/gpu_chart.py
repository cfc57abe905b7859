"""The chart of ``bench_gpu.py``: ms per frame of each contender, per scenario."""

from __future__ import annotations

from pathlib import Path


def _bars(ax, m: dict, colours: dict, title: str) -> None:
    """Median ms per frame with p10-p90 whiskers, one bar per contender."""
    names = list(m["median_ms"])
    med = [m["median_ms"][k] for k in names]
    lo = [m["median_ms"][k] - m["p10_ms"][k] for k in names]
    hi = [m["p90_ms"][k] - m["median_ms"][k] for k in names]
    ax.bar(range(len(names)), med, yerr=[lo, hi], capsize=3,
           color=[colours.get(k, "C5") for k in names])
    ax.set_xticks(range(len(names)), names, rotation=25, ha="right", fontsize=8)
    for j, v in enumerate(med):
        ax.text(j, v, f"{v:.1f}", ha="center", va="bottom", fontsize=8)
    ax.set_title(title, fontsize=9)
    ax.set_ylabel("ms per 1920 x 1080 frame (median, p10-p90)")


def chart(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scen = res["scenarios"]
    fig, axes = plt.subplots(2, 4, figsize=(22, 10.5))
    colours = {"cpu": "C3", "cpu (reused buffer)": "C1", "gpu frame": "C0",
               "gpu to numpy": "C2", "gpu frame, uniform cells by copy shader": "C9",
               "gpu blend shader alone": "C7", "gpu frame from the packed layer": "C4"}
    flat = iter(axes[0])
    for label, sc in scen.items():
        for blend in ("linear", "histogram"):
            m = sc[blend]
            acc = sc["accuracy"][blend]["max_abs_diff"]
            ratio = m["cpu_over_contender_median"].get("gpu frame", float("nan"))
            _bars(next(flat), m, colours,
                  f"{label}, {blend}\n(map cells blended {sc['mixed_cell_fraction']:.1%}; "
                  f"cpu / gpu frame {ratio:.2f}x; max |gpu-cpu| {acc})")
    ax = axes[1][0]
    if "converted" in res:
        c = res["converted"]
        ratio = c["linear"]["cpu_over_contender_median"]["gpu frame"]
        _bars(ax, c["linear"], colours,
              f"converted photo, shaped borders + colour map (scale {c['colour_map_scale']})\n"
              f"cells blended {c['mixed_cell_fraction']:.1%}; cpu / gpu frame {ratio:.2f}x; "
              f"max |gpu-cpu| {c['max_abs_diff']}")
    else:
        ax.set_axis_off()
    rows = res["perspective"]["rows"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    marks = dict(zip(methods, "os^vDP", strict=False))
    ax = axes[1][1]
    for i, name in enumerate(methods):
        pts = [r for r in rows if r["method"] == name]
        ax.plot([p["ms_per_frame"] for p in pts], [p["psnr_db"] for p in pts],
                marks[name], color=f"C{i}", label=name)
        for p in pts:
            ax.annotate(f"{p['pitch']:g}°", (p["ms_per_frame"], p["psnr_db"]), fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("ms per 1280 x 720 frame (median)")
    ax.set_ylabel("PSNR against the supersampled reference (dB)")
    ax.set_title(f"perspective frames, {res['perspective']['project']}", fontsize=9)
    ax.legend(fontsize=8)
    for ax, key, unit in ((axes[1][2], "psnr_db", "PSNR (dB)"),
                          (axes[1][3], "ms_per_frame", "ms per frame (median)")):
        for i, name in enumerate(methods):
            pts = [r for r in rows if r["method"] == name]
            ax.plot([p["pitch"] for p in pts], [p[key] for p in pts], "-" + marks[name],
                    color=f"C{i}", label=name)
        ax.set_xlabel("camera pitch (degrees below the horizontal)")
        ax.set_ylabel(unit)
        if key == "ms_per_frame":
            ax.set_yscale("log")
        ax.set_title(f"{unit} by pitch, 1280 x 720", fontsize=9)
        ax.legend(fontsize=8)
    fig.suptitle(f"GPU renderer on {res['gl_renderer']} vs CPU, same run, "
                 f"{res['cpu_count']} cores (load {res['load_average_start']:.1f} at start, "
                 f"{res['load_average_end']:.1f} at end)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)
