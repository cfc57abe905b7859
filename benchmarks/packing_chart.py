"""The chart of ``bench_packing.py``: bytes per map and lookup ratios."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

CHART_FORMATS = ["terratheme_compact", "terratheme_streams", "jpegxl_e10", "jpegxl_e9",
                 "avif_lossless", "webp_lossless", "geotiff_zstd19", "png9"]


def chart(maps: list[dict], path: Path) -> None:
    """Four panels: bytes, decode time, batched lookup, pack time."""
    fig, axes = plt.subplots(1, 4, figsize=(22, 5.5))
    names = [m["name"] for m in maps]
    width = 0.8 / len(CHART_FORMATS)
    for ax, key, label, log in ((axes[0], "bytes", "file kB (log)", True),
                                (axes[1], "decode_s", "decode whole map, s (log)", True)):
        for i, f in enumerate(CHART_FORMATS):
            vals = [m.get(f, {}).get(key, np.nan) for m in maps]
            vals = [v / 1e3 if key == "bytes" else v for v in vals]
            ax.bar(np.arange(len(maps)) + i * width, vals, width, label=f)
        ax.set_xticks(np.arange(len(maps)) + 0.4, names, fontsize=8)
        ax.set_yscale("log" if log else "linear")
        ax.set_ylabel(label)
        ax.legend(fontsize=7)
    axes[0].set_title("File size (lower is better; no bar: did not finish)")
    axes[1].set_title("Decode time (ours: to the random-access layer)")
    ax = axes[2]
    keys = ["numpy_dense_ns", "compiled_dense_1t_ns", "compiled_dense_2t_ns", "packed_1t_ns",
            "packed_2t_ns", "tiled_2t_ns", "gpu_shader_ns"]
    for i, k in enumerate(keys):
        ax.bar(np.arange(len(maps)) + i * 0.8 / len(keys), [m.get(k, np.nan) for m in maps],
               0.8 / len(keys), label=k[:-3])
    ax.set_xticks(np.arange(len(maps)) + 0.4, names, fontsize=8)
    ax.set_ylabel("ns per texel (10^6 random texels)")
    ax.set_title("Batched random access (gpu_shader: llvmpipe, with upload and read-back)")
    ax.legend(fontsize=7)
    ax = axes[3]
    ax.bar(names, [m["pack_s"] for m in maps], color="tab:green", label="pack")
    ax.axhline(1.5, color="red", ls="--", label="goal 1.5 s")
    ax.set_ylabel("seconds")
    ax.set_title("Pack time (scan, runs, random-access table)")
    ax.legend(fontsize=8)
    for lab in ax.get_xticklabels():
        lab.set_fontsize(8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
