"""The chart of ``bench_fidelity.py``: fidelity against bytes per area.

Three panels against the area's bits per photo pixel (log): dE8, detail and
the texture's mIoU over the classification's; every variant of ``convert``
as points joined into curves (cell sizes, colour-map targets), the option
trials as triangles, the photo as JPEG / WebP / AVIF on the same axes (their
ladder of budgets, and plus markers at the defaults' bytes), the goals dotted.

Issue 34 (part ``structure``, :func:`structure_chart`, drawn as ``fidelity.png``
when present; the chart above then goes to ``fidelity_variants.png``): dE8,
structure 1/4, structure 1/8, detail and placement against bits per pixel, the texture
at the three budgets and the old default, JPEG and AVIF at their best
operating point at the same bytes.
"""

from __future__ import annotations

import numpy as np
from fidelity_peers import CODECS

#: the chart's curves: (label, colour, variants joined by a line)
CURVES = (("default (cell auto), fixed cells 8-64", "crimson",
           ("default", "cell-8", "cell-16", "cell-32", "cell-64")),
          ("paper's rule (cell auto), fixed cells 8-64", "grey",
           ("paper-rule", "paper-cell-8", "paper-cell-16", "paper-cell-32", "paper-cell-64")),
          ("colour-map target 1.5 / 2 (default) / 3 / 4", "darkorange",
           ("cmap-1.5", "default", "cmap-3.0", "cmap-4.0")))
PEER_COLOURS = ("tab:blue", "tab:green", "tab:purple")
TRIAL_STYLES = (("^", "teal"), ("v", "olive"), ("<", "saddlebrown"), (">", "black"))


def chart(result, path, goals):
    """dE8, detail and mIoU ratio against bits per pixel: variants, peers, goals."""
    if "structure" in result:
        structure_chart(result["structure"], path, goals)
        if "variants" not in result:
            return
        path = path.with_name(path.stem + "_variants" + path.suffix)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    summ = result["variants"]["summary"]
    var = summ["variants"]
    fig, axes = plt.subplots(1, 3, figsize=(19, 6.5))
    panels = (("dE8", "dE8: mean CIEDE2000 after a sigma-8 blur (lower is better)",
               goals["mean_dE8"]),
              ("detail", "detail: band-pass energy over the photo's (1 = as much)",
               goals["detail"]),
              ("miou_ratio", "texture mIoU / full-resolution classification mIoU",
               goals["miou_ratio"]))
    for ax, (key, ylabel, goal) in zip(axes, panels, strict=True):
        for label, colour, names in CURVES:
            pts = sorted((var[n]["bpp"], var[n][key], n) for n in names)
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", color=colour, label=label,
                    ms=4)
            for x, y, n in pts:
                if n != "default":
                    ax.annotate(n.split("-")[-1], (x, y), fontsize=7, color=colour,
                                xytext=(3, -9 if colour == "darkorange" else 3),
                                textcoords="offset points")
        ax.plot(var["default"]["bpp"], var["default"][key], "*", color="crimson", ms=16,
                label="default")
        for n, marker in (("no-colour-map", "s"), ("linear-ramp", "D")):
            ax.plot(var[n]["bpp"], var[n][key], marker, color="navy", mfc="none", ms=8, label=n)
        trials = [(n, t["summary"]["variants"]["default"])
                  for n, t in result.get("trials", {}).items() if "summary" in t]
        for (n, t), (marker, colour) in zip(trials, TRIAL_STYLES, strict=False):
            ax.plot(t["bpp"], t[key], marker, color=colour, ms=9, label=f"trial: {n}")
        if key != "miou_ratio":
            for c, colour in zip(CODECS, PEER_COLOURS, strict=True):
                lad = summ["peers_ladder"][c.name]
                pts = [(float(b), lad[b][key]) for b in lad if lad[b][key] is not None]
                ax.plot([p[0] for p in pts], [p[1] for p in pts], "x--", color=colour,
                        label=f"photo as {c.name} q{c.quality}, downscaled to fit")
                at = summ["peers_at_default_bytes"][c.name]
                if at[key] is not None:
                    ax.plot(var["default"]["bpp"], at[key], "P", color=colour, ms=9)
        for g in np.atleast_1d(goal):
            ax.axhline(g, color="k", lw=0.7, ls=":")
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("area bytes x 8 / photo pixels (bits per pixel, log)")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3, which="both")
    axes[2].set_title("(not defined for the peers)", fontsize=9)
    axes[0].legend(fontsize=7.5)
    rows = result["variants"]["photos"]
    counts = {f: sum(r["folder"] == f for r in rows) for f in dict.fromkeys(r["folder"]
                                                                           for r in rows)}
    fig.suptitle("bench_fidelity: means over " + ", ".join(f"{n} {f}" for f, n in counts.items())
                 + " photos; plus markers: peers at the defaults' bytes; dotted lines: goals")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def structure_chart(part, path, goals):
    """Issue 34: every axis against bits per pixel, the texture's budgets and the peers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    summ = part["summary"]
    budgets = sorted((v for v in summ if v.startswith("budget ") and "," not in v),
                     key=lambda v: summ[v]["bpp"])
    panels = (("dE8", "dE8 (lower is better)"), ("s4", "structure 1/4: SSIM of luminance"),
              ("s8", "structure 1/8: SSIM of luminance"), ("detail", "detail (goal 0.8-1.25)"),
              ("placement", "placement: RMS log2 detail ratio of 32 px blocks (lower is better)"))
    panels = tuple(p for p in panels if p[0] in summ[budgets[0]])  # older results had no placement
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 6))
    for ax, (key, label) in zip(axes, panels, strict=True):
        xs = [summ[v]["bpp"] for v in budgets]
        ax.plot(xs, [summ[v][key] for v in budgets], "o-", color="crimson", ms=6,
                label="texture (budgets " + ", ".join(v.split()[1] for v in budgets) + ")")
        for c, colour in (("jpeg", "tab:blue"), ("avif", "tab:purple")):
            ax.plot(xs, [summ[v]["peers"][c][key] for v in budgets], "x--", color=colour,
                    label=f"photo as {c}, best scale x quality at the texture's bytes")
        for v, marker in (("old default", "*"), ("budget 0.04, whole themes", "s")):
            if v in summ:
                ax.plot(summ[v]["bpp"], summ[v][key], marker, color="grey", ms=11, mfc="none",
                        label=v)
                ax.plot(summ[v]["bpp"], summ[v]["peers"]["avif"][key], "P", color="tab:purple",
                        ms=7, mfc="none")
        if key == "detail":
            for g in goals["detail"]:
                ax.axhline(g, color="k", lw=0.7, ls=":")
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ticks = [float(v.split()[1]) for v in budgets]
        ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
        ax.set_xlabel("area bytes x 8 / photo pixels (bits per pixel, log)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=7.5)
    fig.suptitle(f"bench_fidelity structure (issue 34): means over {len(part['photos'])} photos; "
                 "open plus: AVIF at the old default's and whole-themes' bytes")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
