"""Editor benchmark: stroke-to-preview latency and undo memory (issue 5).

Measures, on 2048 x 2048 and 16384 x 16384 texel maps (cell 16 x 16, the
shipped themes):

* **ours**: one brush segment (a mouse move, radius 3 vertices) through
  ``EditDocument.stroke_to`` -> ``RenderPreview.refresh`` (dirty cells only,
  splits kept incrementally) -> the window's image pyramid update; and a
  whole stroke (press, 8 moves, release);
* reference **region render alone**: the same dirty region through
  ``render_cells(region=...)`` without the edit bookkeeping (the floor);
* peer **full re-render**: ``render_cells`` of the whole map after a stroke;
* memory of 1,000 undo steps (random strokes) vs 1,000 whole-grid snapshots
  (and vs whole-render snapshots).

Writes ``benchmarks/results/editor.json`` and ``editor.png``.
Run: ``.venv/bin/python benchmarks/bench_editor.py``.
"""

from __future__ import annotations

import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from terratheme.app.editor.imaging import ZoomPyramid  # noqa: E402
from terratheme.app.editor.newproject import default_library  # noqa: E402
from terratheme.core.edit import EditDocument, RenderPreview  # noqa: E402
from terratheme.core.model.grid import IndexGrid  # noqa: E402
from terratheme.core.model.project import ThematicTexture  # noqa: E402
from terratheme.core.render.renderer import render_cells  # noqa: E402

OUT = REPO / "benchmarks" / "results"
CELL = (16, 16)
SIZES = (2048, 16384)


def blob_grid(size: int, k: int, seed: int) -> np.ndarray:
    """A realistic index grid: smooth random fields, argmax -> k themes in blobs."""
    import cv2

    g = size // CELL[0] + 1
    rng = np.random.default_rng(seed)
    fields = [cv2.GaussianBlur(rng.random((g, g), dtype=np.float32), (0, 0), 4) for _ in range(k)]
    return np.argmax(np.stack(fields), axis=0).astype(np.uint8)


def timed(fn, repeat: int) -> list[float]:
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


class Setup:
    """One map size: texture, live preview, the window's pyramid and an edit document."""

    def __init__(self, size: int, lib) -> None:
        self.size = size
        self.lib = lib
        self.tex = ThematicTexture(IndexGrid(blob_grid(size, min(6, len(lib)), size), CELL), lib)
        t0 = time.perf_counter()
        self.preview = RenderPreview(self.tex)
        self.init_s = time.perf_counter() - t0
        self.pyramid = ZoomPyramid(self.preview.image)
        self.doc = EditDocument(self.tex)
        self.regions: list[tuple[int, int, int, int]] = []
        self.doc.events.grid.connect(self._on_change)
        self.seg, self.stroke, self.api, self.undo_t = [], [], [], []

    def _on_change(self, ch) -> None:
        r = self.preview.refresh(ch)
        if r is not None:
            self.pyramid.update_region(*r)
            self.regions.append(r)

    def one_stroke(self, rng, with_peer: bool) -> None:
        g = self.tex.grid.indices.shape[0]
        x, y = rng.uniform(8, g - 8, 2)
        value = int(rng.integers(len(self.lib)))
        t = time.perf_counter()
        self.doc.begin_stroke(value, (x, y), 3.0)
        for _ in range(8):
            x, y = x + rng.uniform(-2, 2), y + rng.uniform(-2, 2)
            ts = time.perf_counter()
            self.doc.stroke_to((x, y), 3.0)
            self.seg.append(time.perf_counter() - ts)
        self.doc.end_stroke()
        self.stroke.append(time.perf_counter() - t)
        if with_peer and self.regions:
            # Peer: the same dirty region rendered alone through the public API.
            r = self.regions[-1]
            self.api += timed(lambda: render_cells(self.tex.grid.indices, self.lib.textures,
                                                   CELL, r), 1)

    def finish(self, rng) -> dict:
        tex, lib, size = self.tex, self.lib, self.size
        # Peer: a fresh full render after a stroke (what a naive editor does).
        full_times = timed(lambda: render_cells(tex.grid.indices, lib.textures, CELL),
                           2 if size > 4096 else 5)
        fresh = render_cells(tex.grid.indices, lib.textures, CELL)
        identical = bool(np.array_equal(fresh, self.preview.image))
        del fresh
        # Memory: 1,000 undo steps of random strokes.
        mem_doc = EditDocument(tex)
        g = tex.grid.indices.shape[0]
        for _ in range(1000):
            x, y = rng.uniform(0, g, 2)
            r = float(rng.uniform(1, 6))
            mem_doc.begin_stroke(int(rng.integers(len(lib))), (x, y), r)
            for _ in range(int(rng.integers(5, 20))):
                x, y = x + rng.uniform(-3, 3), y + rng.uniform(-3, 3)
                mem_doc.stroke_to((x, y), r)
            mem_doc.end_stroke()
        w, h = tex.grid.texture_size
        med = lambda v: float(np.median(v)) * 1000  # noqa: E731
        p95 = lambda v: float(np.percentile(v, 95)) * 1000  # noqa: E731
        return {
            "map_texels": [w, h],
            "grid_vertices": list(tex.grid.indices.shape),
            "initial_full_render_s": self.init_s,
            "segment_ms_median": med(self.seg),
            "segment_ms_p95": p95(self.seg),
            "stroke_ms_median": med(self.stroke),
            "stroke_ms_p95": p95(self.stroke),
            "region_api_ms_median": med(self.api),
            "full_rerender_ms_median": med(full_times),
            "undo_ms_median": med(self.undo_t),
            "preview_equals_fresh_render": identical,
            "ratio_full_over_segment": med(full_times) / med(self.seg),
            "ratio_full_over_stroke": med(full_times) / med(self.stroke),
            "undo_1000_steps_bytes": mem_doc.history.nbytes,
            "undo_1000_changed_vertices": int(sum(
                c.atom.count for step in mem_doc.history.undo_steps for c in step.changes)),
            "grid_snapshots_1000_bytes": 1000 * tex.grid.indices.nbytes,
            "render_snapshots_1000_bytes": 1000 * w * h * 3,
            "ratio_grid_snapshots_over_undo": 1000 * tex.grid.indices.nbytes
            / mem_doc.history.nbytes,
        }


def _grouped_log_bars(ax, sizes: list[str], series: list[tuple[str, list[float]]],
                      width: float) -> None:
    """Bars of every ``(label, value per size)`` side by side in one group per size, log y."""
    xs = np.arange(len(sizes))
    for i, (label, vals) in enumerate(series):
        bars = ax.bar(xs + (i - (len(series) - 1) / 2) * width, vals, width, label=label)
        ax.bar_label(bars, fmt="%.3g", fontsize=7)
    ax.set_yscale("log")
    ax.set_xticks(xs, [f"{s} x {s}" for s in sizes])


def chart(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sizes = list(results)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    series = [("segment_ms_median", "ours: one brush move"),
              ("stroke_ms_median", "ours: 9-move stroke, all 9 updates"),
              ("region_api_ms_median", "peer: render_cells(region) alone"),
              ("full_rerender_ms_median", "peer: full re-render")]
    _grouped_log_bars(ax1, sizes, [(label, [results[s][key] for s in sizes])
                                   for key, label in series], 0.2)
    ax1.axhline(30, color="red", ls="--", lw=1, label="goal 30 ms")
    ax1.set_ylabel("milliseconds (median, log)")
    ax1.set_title("Brush stroke -> updated preview")
    ax1.legend(fontsize=7, loc="upper left")
    mem = [("undo_1000_steps_bytes", "ours: 1,000 undo steps"),
           ("grid_snapshots_1000_bytes", "1,000 grid snapshots"),
           ("render_snapshots_1000_bytes", "1,000 render snapshots")]
    _grouped_log_bars(ax2, sizes, [(label, [results[s][key] / 2**20 for s in sizes])
                                   for key, label in mem], 0.27)
    ax2.set_ylabel("MiB (log)")
    ax2.set_title("Undo memory")
    ax2.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    lib = default_library()
    rng = np.random.default_rng(0)
    setups = [Setup(size, lib) for size in SIZES]
    # Interleave the sizes stroke by stroke so machine load hits both alike.
    for i in range(80):
        for st in setups:
            st.one_stroke(rng, with_peer=i % 4 == 0)
    # Undo whole strokes, interleaved too (before the full-render peers disturb the caches).
    for _ in range(20):
        for st in setups:
            st.undo_t += timed(st.doc.undo, 1)
    results = {}
    for st in setups:
        results[str(st.size)] = st.finish(rng)
        print(st.size, json.dumps(results[str(st.size)], indent=1), flush=True)
    doc = {
        "machine": {"python": platform.python_version(), "cpu": platform.processor(),
                    "note": "2 cores shared with other benchmarks: compare ratios"},
        "cell": list(CELL),
        "themes": lib.names,
        "results": results,
        "growth_16384_over_2048_segment": results["16384"]["segment_ms_median"]
        / results["2048"]["segment_ms_median"],
    }
    (OUT / "editor.json").write_text(json.dumps(doc, indent=1))
    chart(results, OUT / "editor.png")


if __name__ == "__main__":
    main()
