"""The accuracy-against-speed chart of ``bench_classify.py`` (one point per method)."""

from __future__ import annotations


def chart(result, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    panels = [("(a) Dubai, unseen tile; parts 001-003 of each tile (18 photos, all methods)",
               result["across_tiles"], lambda r: r["subset_001_003"]["miou"], 0.45),
              ("(b) scribbles <= 1% of pixels, mean mIoU", result["scribbles"],
               lambda r: r["mean_miou_over_photos"], 0.60)]
    # One colour and marker per method in both panels.
    names = list(dict.fromkeys(m for _t, res, _g, _goal in panels for m in res if m != "coverage"))
    markers = "osDv^P*Xhd<>p8H"
    colours = plt.get_cmap("tab20").colors
    for ax, (title, res, get, goal) in zip(axes, panels, strict=True):
        for m, r in ((m, r) for m, r in res.items() if m != "coverage"):
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
    fig.suptitle("terratheme classify: accuracy vs speed per feature set / classifier "
                 "(dashed: goal mIoU, dotted: 5 Mpx/s)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
