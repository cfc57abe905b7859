"""Roads through ``convert --model aerial``: texture road IoU and connectivity (issues 34, 35).

Run: ``nice -n 10 .venv/bin/python benchmarks/bench_roads.py [--quick] [--chart]``
(needs ``../shared/data``). Writes ``benchmarks/results/roads.json`` and ``roads.png``;
``--quick``: one photo, the defaults only, to /tmp; ``--chart`` only redraws the chart.

Photos: the 9 Dubai photos of tile 1 (held out of the shipped network's training,
``models/models.json``), the Dubai photo of the README's road picture (005t2, a
training tile: optimistic) and LoveDA 0 and 1 (another continent and sensor; road
is their class 3 too).

Per photo the shipped network (``load_model("aerial")``, class 3 = road) classifies
once; ``convert_photo`` runs with it as ``convert --model aerial`` does (the defaults
timed end to end, Mpx/s), then each option variant (:data:`VARIANTS`) through
``convert_photo`` with the network's answer replayed (:class:`Replay`), so the variants
differ from the defaults only in their options.

Scored on the mask's valid pixels (Dubai classes 1-5, LoveDA 1-7), road against the
rest, for the classification (``labels``) and the texture (the grid's label view
``render_labels`` over the photo, each theme mapped back to the class it was cut for;
the same view with each theme named by its majority true class, as ``bench_fidelity``
scores it, is kept as ``road_iou_majority``):
  road_iou        IoU of road (per photo; pooled over the held-out photos in the summary);
  ratio           texture road IoU / classification road IoU (the goal: >= 0.9);
  road_kept       the texture's road IoU against the classification's road (what the grid
                  keeps of the network's answer, as the cell choice's ``class_target`` sees it);
  components      8-connected road components of the prediction (the mask's beside it),
                  and those of at least 100 pixels;
  skeleton_cover  share of the mask's road skeleton (``skeletonize``) predicted road:
                  how much of the network's centre lines survives;
  bytes           ``texture_cost`` (area = packed grid + colour map; themes apart);
  dE8, detail,    as ``bench_fidelity``: under the default byte budget the colour map takes
  placement       what the grid leaves, so a finer grid costs colour, not bytes.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from skimage.measure import label as connected
from skimage.morphology import skeletonize

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))

from bench_classify import DATA, load  # noqa: E402
from classify_eval import class_iou_scores  # noqa: E402
from fidelity_peers import placement_score  # noqa: E402
from terratheme.core.classify import load_model  # noqa: E402
from terratheme.core.convert.colour_fit import ColourMapOptions  # noqa: E402
from terratheme.core.convert.photo import ConvertOptions, convert_photo  # noqa: E402
from terratheme.core.fidelity import (  # noqa: E402
    colour_error,
    detail_ratio,
    texture_cost,
)
from terratheme.core.render.project import render_project  # noqa: E402
from terratheme.core.render.renderer import RenderOptions, render_labels  # noqa: E402

OUT = REPO / "benchmarks" / "results"
ROAD = 3
#: folder -> valid mask values (road is 3 in both)
VALID = {"dubai": (1, 2, 3, 4, 5), "loveda": (1, 2, 3, 4, 5, 6, 7)}
HOLDOUT = tuple(("dubai", f"image_part_{i:03d}t1.jpg") for i in range(1, 10))
OTHERS = (("dubai", "image_part_005t2.jpg"), ("loveda", "loveda_0.png"),
          ("loveda", "loveda_1.png"))
DEFAULT = ConvertOptions()
#: name -> convert options; "default" is ``convert --model aerial`` itself
VARIANTS = {
    "default": DEFAULT,
    "class-target-0.7": replace(DEFAULT, class_target=0.7),
    "keep-specks": replace(DEFAULT, keep_specks=True),
    "cells<=8": replace(DEFAULT, candidates=tuple(c for c in DEFAULT.candidates if c <= 8)),
    "budget-0.08": replace(DEFAULT, colour_map=ColourMapOptions(budget=0.08)),
    "budget-0.08+cells<=8": replace(
        DEFAULT, candidates=tuple(c for c in DEFAULT.candidates if c <= 8),
        colour_map=ColourMapOptions(budget=0.08)),
    "budget-0.16": replace(DEFAULT, colour_map=ColourMapOptions(budget=0.16)),
    "cells<=6": replace(DEFAULT, candidates=tuple(c for c in DEFAULT.candidates if c <= 6)),
    "cells<=4": replace(DEFAULT, candidates=tuple(c for c in DEFAULT.candidates if c <= 4)),
    "cells<=4+budget-0.06": replace(
        DEFAULT, candidates=tuple(c for c in DEFAULT.candidates if c <= 4),
        colour_map=ColourMapOptions(budget=0.06)),
    "cells<=4+budget-0.08": replace(
        DEFAULT, candidates=tuple(c for c in DEFAULT.candidates if c <= 4),
        colour_map=ColourMapOptions(budget=0.08)),
    "cell-8": replace(DEFAULT, cell=8),
    "cell-6": replace(DEFAULT, cell=6),
    "cell-4": replace(DEFAULT, cell=4),
}
GOAL_RATIO = 0.9
#: components at least this many pixels count in ``components_100px``
MIN_COMPONENT = 100


class Replay:
    """A classifier that answers with one stored classification (the network's, run once)."""

    def __init__(self, model, result) -> None:
        self.class_names = model.class_names
        self.classes = model.classes
        self.result = result

    def predict(self, photo, progress=None):
        return self.result


def road_scores(pred: np.ndarray, truth: np.ndarray, valid: np.ndarray,
                skeleton: np.ndarray) -> dict:
    """IoU, connectivity and skeleton cover of a (H, W) bool road prediction."""
    t, p = truth & valid, pred & valid
    inter, union = int((t & p).sum()), int((t | p).sum())
    comp = connected(pred, connectivity=2)
    sizes = np.bincount(comp.ravel())[1:]
    n_skel = int(skeleton.sum())
    return {"road_iou": None if union == 0 else round(inter / union, 4),
            "inter": inter, "union": union,
            "components": int(sizes.size),
            "components_100px": int((sizes >= MIN_COMPONENT).sum()),
            "skeleton_cover": None if n_skel == 0 else round(
                float((pred & skeleton).sum() / n_skel), 4)}


def texture_view(result, project, w: int, h: int) -> np.ndarray:
    """The grid's label view over the photo, each theme mapped back to its class (0: none)."""
    view = render_labels(project.grid, region=(0, 0, w, h))
    back = np.zeros(max(int(view.max()), int(result.mapping.lut.max())) + 1, np.uint8)
    for c in result.mapping.classes:
        back[int(result.mapping.lut[c])] = c
    for twin in result.mapping.calm:
        back[twin.twin] = back[twin.theme]
    return back[view], view


def measure_photo(model, folder: str, name: str, variants: dict, log) -> dict:
    photo, mask = load(folder, name)
    h, w = photo.shape[:2]
    mpx = w * h / 1e6
    valid = np.isin(mask, VALID[folder])
    truth = mask == ROAD
    skeleton = skeletonize(truth & valid)
    t = time.perf_counter()
    classified = model.predict(photo)
    predict_s = time.perf_counter() - t
    replay = Replay(model, classified)
    cls = road_scores(classified.labels == ROAD, truth, valid, skeleton)
    true_comp = connected(truth & valid, connectivity=2)
    true_sizes = np.bincount(true_comp.ravel())[1:]
    row = {"folder": folder, "photo": name, "size": [w, h], "mpx": round(mpx, 3),
           "held_out": (folder, name) in HOLDOUT, "load_average": os.getloadavg()[0],
           "road_share": round(float((truth & valid).sum() / max(valid.sum(), 1)), 4),
           "mask_components": int(true_sizes.size),
           "mask_components_100px": int((true_sizes >= MIN_COMPONENT).sum()),
           "predict_s": round(predict_s, 2), "classification": cls, "variants": {}}
    for vname, opts in variants.items():
        t = time.perf_counter()
        # The defaults run the network itself (timed as convert runs); the variants replay it.
        res = convert_photo(photo, opts, model=model if vname == "default" else replay)
        secs = time.perf_counter() - t + (0.0 if vname == "default" else predict_s)
        classes, view = texture_view(res, res.project, w, h)
        tex = road_scores(classes == ROAD, truth, valid, skeleton)
        render = render_project(res.project, (0, 0, w, h),
                                options=RenderOptions(boundary=opts.boundary))
        maj = class_iou_scores(view, np.where(valid, mask, 0), list(VALID[folder]))
        kept = road_scores(classes == ROAD, classified.labels == ROAD, valid, skeleton)
        tex.update(road_iou_majority=maj["iou"].get(ROAD), road_kept=kept["road_iou"],
                   ratio=None if not cls["road_iou"] or tex["road_iou"] is None
                   else round(tex["road_iou"] / cls["road_iou"], 4),
                   dE8=round(colour_error(render, photo), 3),
                   detail=round(detail_ratio(render, photo), 3),
                   placement=placement_score(render, photo),
                   cell=int(res.project.grid.cell[0]), **texture_cost(res.project).as_dict(),
                   bpp=round(texture_cost(res.project).area_bytes * 8 / (w * h), 4),
                   seconds=round(secs, 2), mpx_per_s=round(mpx / secs, 3))
        row["variants"][vname] = tex
        log(f"  {name} {vname}: road IoU cls {cls['road_iou']} tex {tex['road_iou']} "
            f"ratio {tex['ratio']} cell {tex['cell']} comps {cls['components_100px']}/"
            f"{tex['components_100px']} (mask {row['mask_components_100px']}) skel "
            f"{cls['skeleton_cover']}/{tex['skeleton_cover']} {tex['area_bytes']} B "
            f"dE8 {tex['dE8']} detail {tex['detail']} placement {tex['placement']} {secs:.1f} s")
    return row


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return round(float(np.mean(values)), 4) if values else None


def _pooled(scores: list[dict]) -> float | None:
    union = sum(s["union"] for s in scores)
    return round(sum(s["inter"] for s in scores) / union, 4) if union else None


def summarise(rows: list[dict]) -> dict:
    """Per variant, over the held-out photos: means, pooled IoU and the goal."""
    held = [r for r in rows if r["held_out"]] or rows
    cls = [r["classification"] for r in held]
    out = {"photos": [r["photo"] for r in held],
           "classification": {"road_iou_pooled": _pooled(cls),
                               **{k: _mean([c[k] for c in cls]) for k in
                                  ("road_iou", "components", "components_100px",
                                   "skeleton_cover")}},
           "photos_network_road_iou<0.05": [r["photo"] for r in held
                                             if (r["classification"]["road_iou"] or 0) < 0.05],
           "mask_components_100px": _mean([r["mask_components_100px"] for r in held]),
           "mpx_per_s_predict": round(sum(r["mpx"] for r in held)
                                      / sum(r["predict_s"] for r in held), 3),
           "variants": {}}
    base_bytes = sum(r["variants"]["default"]["area_bytes"] for r in held)
    for v in rows[0]["variants"]:
        vs = [r["variants"][v] for r in held]
        pooled = _pooled(vs)
        m = {k: _mean([x[k] for x in vs]) for k in
             ("road_iou", "road_iou_majority", "road_kept", "ratio", "components",
              "components_100px", "skeleton_cover", "dE8", "detail", "placement", "cell",
              "area_bytes", "grid_bytes", "colour_map_bytes", "theme_bytes", "bpp")}
        m.update(road_iou_pooled=pooled,
                 ratio_pooled=None if not pooled else round(
                     pooled / out["classification"]["road_iou_pooled"], 4),
                 area_bytes_vs_default=round(sum(x["area_bytes"] for x in vs) / base_bytes, 3),
                 mpx_per_s=round(sum(r["mpx"] for r in held) / sum(x["seconds"] for x in vs),
                                 3),
                 photos_ratio_below_goal=[r["photo"] for r, x in zip(held, vs, strict=True)
                                          if x["ratio"] is not None and x["ratio"] < GOAL_RATIO])
        m["goal_ratio>=0.9_pooled"] = bool(m["ratio_pooled"] and m["ratio_pooled"] >= GOAL_RATIO)
        out["variants"][v] = m
    return out


def chart(out: dict, path: Path) -> None:
    """Ratio against area bytes and against dE8 per variant; road IoU per photo."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, c, b) = plt.subplots(1, 3, figsize=(16, 4.8))
    s = out["summary"]["variants"]
    for i, (name, m) in enumerate(s.items()):
        style = {"c": f"C{i % 10}", "marker": "o" if i < 10 else "s", "label": name}
        a.scatter([m["area_bytes_vs_default"]], [m["ratio_pooled"]], **style)
        c.scatter([m["dE8"]], [m["ratio_pooled"]], **style)
    for ax, xlabel in ((a, "area bytes (grid + colour map) / the defaults'"),
                       (c, "mean dE8 of the texture (lower is better)")):
        ax.axhline(GOAL_RATIO, color="k", ls="--", lw=0.8, label="goal 0.9")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("texture road IoU / classification's (pooled)")
        ax.grid(True, alpha=0.3)
    a.set_title("held-out Dubai tile 1: road ratio against bytes")
    c.set_title("... and against colour error")
    a.legend(fontsize=7)
    rows = out["rows"]
    x = np.arange(len(rows))
    cls = [r["classification"]["road_iou"] or 0 for r in rows]
    tex = [r["variants"]["default"]["road_iou"] or 0 for r in rows]
    b.bar(x - 0.2, cls, 0.4, label="classification (network)")
    b.bar(x + 0.2, tex, 0.4, label="texture (convert defaults)")
    b.set_xticks(x, [r["photo"].replace("image_part_", "").rsplit(".", 1)[0] for r in rows],
                 rotation=60, fontsize=7)
    b.set_ylabel("road IoU")
    b.set_title("road IoU per photo (last 3: training tile, LoveDA)")
    b.grid(True, axis="y", alpha=0.3)
    b.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one photo, defaults, to /tmp")
    parser.add_argument("--chart", action="store_true", help="only redraw the chart")
    parser.add_argument("--variants", default=",".join(VARIANTS),
                        help="comma-separated variants (default first)")
    args = parser.parse_args()
    out_dir = Path("/tmp") if args.quick else OUT
    result_path = out_dir / "roads.json"
    if args.chart:
        chart(json.loads(result_path.read_text()), out_dir / "roads.png")
        return 0
    if not (DATA / "dubai" / "images").is_dir():
        print(f"{DATA}: no shared data; nothing measured")
        return 0

    def log(msg: str) -> None:
        print(msg, flush=True)

    model = load_model("aerial")
    photos = HOLDOUT[:1] if args.quick else HOLDOUT + OTHERS
    names = ["default"] if args.quick else ["default", *(
        v for v in args.variants.split(",") if v != "default")]
    variants = {v: VARIANTS[v] for v in names}
    rows = []
    for folder, name in photos:
        rows.append(measure_photo(model, folder, name, variants, log))
        out = {"model": "aerial", "holdout_tile": 1, "variants": {
            v: repr(o) for v, o in variants.items()}, "rows": rows,
            "summary": summarise(rows)}
        out_dir.mkdir(exist_ok=True)
        result_path.write_text(json.dumps(out, indent=1) + "\n")
    chart(out, out_dir / "roads.png")
    log(json.dumps(out["summary"], indent=1))
    log(f"wrote {result_path} and roads.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
