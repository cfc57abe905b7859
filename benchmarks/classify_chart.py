"""The charts of ``bench_classify.py``.

(a), (b): accuracy against speed, one point per method; (c): the scribble
protocols at the same budget -- one-shot against two rounds (corrections);
(d): one-shot accuracy against the scribble budget; (e): issue 17's
one-photo-per-tile protocol, each robustness piece on its own; (f): the
shipped aerial model on other datasets against its peers.
"""

from __future__ import annotations

#: the scribble protocols of part "corrections": (variant, colour, label)
_SERIES = (("one-shot", "#9e9e9e", "one-shot, whole budget (same-run peer)"),
           ("round1", "#d9d9d9", "round 1 only (half the budget)"),
           ("corrections", "crimson", "corrections: + half on the errors"),
           ("low-confidence", "darkorange", "prompts: + half on low confidence"))
_PROTOCOL_METHODS = ("rf-default", "rf-noprior", "rf-keepprior", "ilastik")


def chart(result, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    rows = result.get("scribbles_corrections")
    budget = result.get("scribbles_budget")
    fig, axes = plt.subplots(3, 2, figsize=(14, 15.5))
    axes = axes.ravel()
    draws = result["scribbles"].get("draws", 1)
    panels = [("(a) Dubai, unseen tile; parts 001-003 of each tile (18 photos, all methods)",
               result["across_tiles"], lambda r: r["subset_001_003"]["miou"], 0.45),
              (f"(b) one-shot scribbles <= 0.8% of pixels (16 photos), mean mIoU "
               f"(mean of {draws} draws)",
               result["scribbles"], lambda r: r["mean_miou_over_photos"], 0.60)]
    # One colour and marker per method in both panels.
    names = list(dict.fromkeys(m for _t, res, _g, _goal in panels for m in res
                               if isinstance(res[m], dict) and m != "coverage"))
    markers = "osDv^P*Xhd<>p8H"
    colours = plt.get_cmap("tab20").colors
    for ax, (title, res, get, goal) in zip(axes, panels, strict=False):
        for m, r in ((m, r) for m, r in res.items() if m in names):
            i = names.index(m)
            ax.scatter(r["mpx_per_s"], get(r), s=70, marker=markers[i % len(markers)],
                       color=colours[i % len(colours)], label=m,
                       edgecolor="black" if m == "rf-default" else "none")
        ax.legend(fontsize=7, loc="lower left", ncol=2)
        ax.axhline(goal, color="grey", ls="--", lw=1)
        ax.axvline(5.0, color="grey", ls=":", lw=1)
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("predict speed, Mpx/s (2 cores, log)")
        ax.set_ylabel("mIoU")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
    if rows:
        _protocols(axes[2], rows)
    else:
        axes[2].set_visible(False)
    if budget:
        _budget(axes[3], budget)
    else:
        axes[3].set_visible(False)
    if result.get("one_per_tile"):
        _one_per_tile(axes[4], result["one_per_tile"])
    else:
        axes[4].set_visible(False)
    if result.get("aerial"):
        _aerial(axes[5], result["aerial"])
    else:
        axes[5].set_visible(False)
    fig.suptitle("terratheme classify: accuracy vs speed per feature set / classifier "
                 "(dashed: goal mIoU, dotted: 5 Mpx/s)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _protocols(ax, rows):
    """Grouped bars: per method, mean mIoU over 16 photos of each scribble protocol.

    Whiskers span the repeats (independent stroke draws); black dots are the
    Dubai pooled mIoU.
    """
    methods = [m for m in _PROTOCOL_METHODS if m in rows]
    width = 0.8 / len(_SERIES)
    for j, (v, colour, label) in enumerate(_SERIES):
        xs, ys, lo, hi, pooled = [], [], [], [], []
        for i, m in enumerate(methods):
            if v not in rows[m]:
                continue
            r = rows[m][v]
            reps = r.get("mean_miou_per_repeat", [r["mean_miou_over_photos"]])
            xs.append(i + (j - (len(_SERIES) - 1) / 2) * width)
            ys.append(r["mean_miou_over_photos"])
            lo.append(r["mean_miou_over_photos"] - min(reps))
            hi.append(max(reps) - r["mean_miou_over_photos"])
            pooled.append(r["dubai_pooled"]["miou"])
        hatch = "//" if v in ("corrections", "low-confidence") else None
        ax.bar(xs, ys, width, color=colour, edgecolor="black", linewidth=0.6, hatch=hatch,
               label=label, yerr=[lo, hi], capsize=2, error_kw={"lw": 0.8})
        ax.scatter(xs, pooled, s=14, color="black", zorder=5,
                   label="Dubai pooled mIoU" if j == 0 else None)
        for x, y in zip(xs, ys, strict=True):
            ax.text(x, 0.305, f"{y:.3f}", rotation=90, ha="center", va="bottom", fontsize=7,
                    bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.5})
    ax.axhline(0.60, color="grey", ls="--", lw=1)
    ax.set_xticks(range(len(methods)), methods, fontsize=8)
    ax.set_ylim(0.3, 0.8)
    ax.set_ylabel("mean mIoU over 16 photos")
    share = rows.get("low_confidence_share", 0.1)
    ax.set_title(f"(c) the same <= 0.8% budget: one shot vs two rounds (mean of "
                 f"{rows.get('repeats', 1)} draws;\n prompts = lowest {share:.0%} confidence, "
                 "no ground truth chooses where)", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    ax.grid(alpha=0.3, axis="y")


def _budget(ax, budget):
    """Mean mIoU over 16 photos against the scribble budget; whiskers span the draws."""
    for m, colour, below in (("rf-default", "crimson", False), ("rf-cv2", "#999999", True),
                             ("ilastik", "#4c72b0", False)):
        if m not in budget:
            continue
        xs = [100 * float(b) for b in budget[m]]
        rows = list(budget[m].values())
        ys = [r["mean_miou_over_photos"] for r in rows]
        lo = [y - min(r["mean_miou_per_repeat"]) for y, r in zip(ys, rows, strict=True)]
        hi = [max(r["mean_miou_per_repeat"]) - y for y, r in zip(ys, rows, strict=True)]
        ax.errorbar(xs, ys, yerr=[lo, hi], color=colour, marker="o", capsize=3, label=m)
        for x, y in zip(xs, ys, strict=True):
            ax.annotate(f"{y:.3f}", (x, y), textcoords="offset points",
                        xytext=(5, -12) if below else (-30, 6),
                        fontsize=7, color=colour)
    ax.axhline(0.60, color="grey", ls="--", lw=1)
    ax.axvline(1.0, color="grey", ls=":", lw=1)
    ax.set_xlabel("scribble budget, % of the photo's pixels (dotted: the issue's 1% cap)")
    ax.set_ylabel("mean mIoU over 16 photos")
    ax.set_title(f"(d) one-shot scribbles: what more paint buys (mean of {budget['draws']} "
                 "draws, whiskers: the draws)", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)


def _one_per_tile(ax, rows):
    """Bars: mean over held-out tiles of the tile mIoU (mean of the draws); whiskers: the
    draws; dots: mean mIoU per photo."""
    methods = [m for m, r in rows.items() if isinstance(r, dict) and "mean_tile_miou" in r]
    ys = [rows[m]["mean_tile_miou"] for m in methods]
    per = [rows[m]["mean_tile_miou_per_draw"] for m in methods]
    lo = [max(y - min(p), 0.0) for y, p in zip(ys, per, strict=True)]
    hi = [max(max(p) - y, 0.0) for y, p in zip(ys, per, strict=True)]
    colours = ["crimson" if m == "rf-default" else "#4c72b0" if m == "ilastik" else "#9e9e9e"
               for m in methods]
    xs = range(len(methods))
    ax.bar(xs, ys, color=colours, edgecolor="black", linewidth=0.6, yerr=[lo, hi], capsize=3)
    ax.scatter(xs, [rows[m]["mean_photo_miou"] for m in methods], color="black", s=16,
               zorder=5, label="mean mIoU per photo")
    for x, y in zip(xs, ys, strict=True):
        ax.text(x, 0.205, f"{y:.3f}", rotation=90, ha="center", va="bottom", fontsize=7,
                bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.5})
    ax.axhline(0.45, color="grey", ls="--", lw=1)
    ax.set_xticks(list(xs), methods, fontsize=7, rotation=30, ha="right")
    ax.set_ylim(0.2, 0.5)
    ax.set_ylabel("mIoU of the held-out tile, mean over tiles")
    ax.set_title(f"(e) trained on one photo per other Dubai tile, held-out tile scored\n"
                 f"({len(rows.get('draws', []))} draws of photos, whiskers: draws; "
                 "ilastik: draw 0, parts 001-003; dashed: goal)", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3, axis="y")


def _aerial(ax, result):
    """Grouped bars: the shipped model and its peers, mIoU per photo of other datasets."""
    methods = [m for m in ("aerial", "aerial-adapt", "scribbles", "kmeans-oracle")
               if m in result]
    photos = list(result[methods[0]]["per_photo"])
    width = 0.8 / len(methods)
    colours = {"aerial": "crimson", "aerial-adapt": "#f4a582", "scribbles": "#9e9e9e",
               "kmeans-oracle": "#4c72b0"}
    for j, m in enumerate(methods):
        xs = [i + (j - (len(methods) - 1) / 2) * width for i in range(len(photos))]
        ys = [result[m]["per_photo"][p]["miou"] for p in photos]
        ax.bar(xs, ys, width, color=colours[m], edgecolor="black", linewidth=0.6,
               label=f"{m} (mean {result[m]['mean_miou']:.3f})")
    ax.set_xticks(range(len(photos)), [p.split(".")[0][:18] for p in photos], fontsize=7)
    ax.set_ylim(0, 1)
    ax.set_ylabel("mIoU over the classes shared with the legend")
    ax.set_title(f"(f) shipped model {result['model']} ({result['model_bytes']:,} B), no labels "
                 "of these photos\n(scribbles: 0.8% strokes of the photo itself, its legend)",
                 fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3, axis="y")
