"""Fidelity of ``convert`` against bytes per area, with JPEG, WebP and AVIF as peers (issue 13).

Run: ``.venv/bin/python benchmarks/bench_fidelity.py [variants] [defaults54] [trials]
[--quick] [--chart]`` (all parts by default; naming some reruns those and keeps
the others from the last fidelity.json; ``--chart`` only redraws the chart).
Writes ``benchmarks/results/fidelity.json`` and ``fidelity.png``; part
``structure`` also the README pictures ``docs/fidelity/*.jpg`` and ``*.png``
(photo | texture at today's defaults, Dubai photos only: CC0). On 2 cores shared
with other jobs (load average 5-9) the parts took about 17, 7, 10 and 7 minutes;
``--quick``: two photos, no pictures, to /tmp.

Photos (with masks, ``../shared/data``): parts ``variants`` and ``trials``
run on the 16 photos of ``bench_classify.scribble_sets()``: Dubai parts 004
and 005 of each of the 6 tiles (12 photos, the bundled sample among them),
LoveDA 0 and 1, Potsdam, DeepGlobe 6399 cropped to its top-left 1536^2 (all
54 Dubai photos times 15 variants would take over an hour on 2 shared
cores). Part ``defaults54`` runs the defaults and the peers at equal bytes
on all 54 Dubai photos; part ``trials`` runs option variants
(:data:`TRIALS`) as if they were the defaults (texture, peers at their own
bytes, goals), part ``trials54`` the best of them (:data:`BEST_TRIAL`) on
all 54 Dubai photos.

Per photo: ``convert_photo`` with the defaults (timed end to end), then each
variant from the same classification and themes (they depend on neither
the cell, the colour map nor the boundary) through
``core.convert.step.grid_and_colour``, as ``convert_photo`` calls it;
variants whose cell is chosen automatically reuse the defaults' choice (the
choice depends on the labels and ``keep_specks`` only; ``keep-specks``
chooses its own) and their time counts the defaults'
classification, themes and cell-choice times (progress timestamps) plus
their own. The composition is checked against ``convert_photo`` on the
first photo (same grid, same colour map).

Measures (``core.fidelity``): dE8, detail, structure (mIoU of the label view
``render_labels`` of the grid cropped to the photo against the mask, each
theme mapped to its majority class; the full-resolution classification's
own mIoU on the same photo, and the ratio), small and thin classes on their
own (:data:`THIN`), bytes (``texture_cost``: area = packed grid + colour
map, themes), convert seconds and Mpx/s. Peers (``fidelity_peers.py``): the
photo as JPEG, WebP, AVIF at the defaults' ``area_bytes`` (the goals) and at
a ladder of bits per pixel (:data:`LADDER_BPP`, the chart's curves).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from dataclasses import asdict, replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from bench_classify import DATA, load, scribble_sets  # noqa: E402
from classify_eval import class_iou_scores  # noqa: E402
from fidelity_chart import chart  # noqa: E402
from fidelity_peers import CODECS, PEER_MAKERS, best_peers, score_image, score_peers  # noqa: E402
from terratheme.core.convert.cell_choice import cell_within_budget, choose_cell_size  # noqa: E402
from terratheme.core.convert.colour_fit import ColourMapOptions  # noqa: E402
from terratheme.core.convert.labels_to_grid import apply_lut  # noqa: E402
from terratheme.core.convert.photo import ConvertOptions, convert_photo  # noqa: E402
from terratheme.core.convert.step import (  # noqa: E402
    assign_themes,
    classify_photo,
    detail_mapping,
    grid_and_colour,
    grid_budget,
)
from terratheme.core.fidelity import colour_error, detail_ratio, texture_cost  # noqa: E402
from terratheme.core.io.images import read_image, write_image  # noqa: E402
from terratheme.core.model.project import ThematicTexture  # noqa: E402
from terratheme.core.render.project import render_project  # noqa: E402
from terratheme.core.render.renderer import RenderOptions, render_labels  # noqa: E402
from terratheme.core.themes.calm import twin_parents  # noqa: E402

OUT = REPO / "benchmarks" / "results"
DOCS = REPO / "docs" / "fidelity"
SAMPLE = REPO / "sample_maps" / "dubai_marina.jpg"
DEFAULT = ConvertOptions()
PAPER = replace(DEFAULT, colour_map=None, boundary=None)
#: name -> options; "default" is convert_photo itself
VARIANTS = {
    "default": DEFAULT,
    "no-colour-map": replace(DEFAULT, colour_map=None),
    "linear-ramp": replace(DEFAULT, boundary=None),
    "paper-rule": PAPER,
    "keep-specks": replace(DEFAULT, keep_specks=True),
    **{f"cell-{c}": replace(DEFAULT, cell=c) for c in (8, 16, 32, 64)},
    **{f"paper-cell-{c}": replace(PAPER, cell=c) for c in (8, 16, 32, 64)},
    **{f"cmap-{t}": replace(DEFAULT, colour_map=ColourMapOptions(target=t))
       for t in (1.5, 3.0, 4.0)},
}
#: small and thin classes scored on their own: folder -> {class: name}
THIN = {"dubai": {3: "road", 5: "water"}, "loveda": {3: "road", 4: "water"},
        "potsdam": {1: "impervious", 5: "car"}, "deepglobe": {5: "water"}}
#: bits per photo pixel of the peers' curves
LADDER_BPP = (0.003, 0.01, 0.03, 0.1)
#: README pictures of part ``structure``: (picture name, photo) -- CC0, may ship
PICTURES = (("dubai_marina", SAMPLE.name), ("dubai_lake", "image_part_005t1.jpg"),
            ("dubai_villas", "image_part_005t4.jpg"), ("dubai_roads", "image_part_005t2.jpg"))
PICTURE_WIDTH = 1000
#: option variants tried as convert's defaults (texture and peers at their own bytes)
TRIALS = {
    "cells<=16": replace(DEFAULT, candidates=tuple(c for c in DEFAULT.candidates if c <= 16)),
    "cells<=16,cmap-scale-4": replace(
        DEFAULT, candidates=tuple(c for c in DEFAULT.candidates if c <= 16),
        colour_map=ColourMapOptions(scales=(64, 32, 16, 8, 4))),
    "agreement-0.95": replace(DEFAULT, target_agreement=0.95),
}
#: the trial that part "trials54" runs on all 54 Dubai photos
BEST_TRIAL = "cells<=16"
PARTS = ("variants", "defaults54", "trials", "trials54", "structure")
#: part "structure" (issue 34): photos (folder, name), the budgets (bits per pixel; the
#: default, half and double) and the 1:1 crops (name, photo, x, y) of docs/fidelity
STRUCTURE_PHOTOS = (("sample", SAMPLE.name), ("dubai", "image_part_005t1.jpg"),
                    ("dubai", "image_part_005t4.jpg"), ("dubai", "image_part_005t2.jpg"))
BUDGETS = (0.02, 0.04, 0.08)
CROPS = (("crop_town_block", SAMPLE.name, 620, 250), ("crop_road_junction", SAMPLE.name, 640, 480),
         ("crop_shore", SAMPLE.name, 330, 380))
CROP_SIDE = 320
#: the scores of part "structure" (``fidelity_peers.score_image``)
AXES = ("dE8", "s4", "s8", "detail", "placement")
GOALS = {"mean_dE8": 3.0, "detail": (0.8, 1.25), "miou_ratio": 0.9, "dE8_over_peer": 1.0,
         "convert_seconds": 5.0}


def dubai_all():
    """All 54 Dubai photos: (folder, name, classes, crop)."""
    names = sorted(p.name for p in (DATA / "dubai" / "images").glob("*.jpg"))
    return [("dubai", n, [1, 2, 3, 4, 5], None) for n in names]


class Stopwatch:
    """A progress callback that keeps the time each step of ``convert_photo`` was reached."""

    def __init__(self) -> None:
        self.start = time.perf_counter()
        self.reached: dict[int, float] = {}

    def __call__(self, done: int, total: int) -> None:
        self.reached.setdefault(done, time.perf_counter() - self.start)

    def first(self, step: int) -> float:
        return min(t for d, t in self.reached.items() if d >= step)


def variant_project(rgb, res, opts, cell):
    """The project ``convert_photo(rgb, opts)`` makes, from ``res``'s classification and
    themes; and its calm twins (those ``res`` has, unless the variant's grid drops them)."""
    theme_labels = apply_lut(res.labels, res.mapping.lut)
    made = grid_and_colour(rgb, theme_labels, res.mapping, cell=cell,
                           target_agreement=opts.target_agreement,
                           class_target=opts.class_target, candidates=opts.candidates,
                           colour_map=opts.colour_map,
                           render=RenderOptions(boundary=opts.boundary),
                           keep_specks=opts.keep_specks)
    h, w = rgb.shape[:2]
    return ThematicTexture(made.grid, made.mapping.library, {"photo_size": [w, h]},
                           colour_map=None if made.colour is None else made.colour.colour_map
                           ), made.mapping.calm


def score_texture(photo, mask, classes, thin, project, boundary, calm=()):
    """dE8, detail, structure and bytes of one texture; also returns its render. ``calm``:
    the conversion's calm twins, scored as the classes they split."""
    h, w = photo.shape[:2]
    render = render_project(project, (0, 0, w, h), options=RenderOptions(boundary=boundary))
    view = twin_parents(len(project.library), calm)[
        render_labels(project.grid, region=(0, 0, w, h))]
    s = class_iou_scores(view, mask, classes)
    cost = texture_cost(project)
    return {"cell": project.grid.cell[0], "themes": len(project.library),
            "dE8": round(colour_error(render, photo), 3),
            "detail": round(detail_ratio(render, photo), 3), "miou_tex": round(s["miou"], 4),
            "thin_tex": {thin[k]: s["iou"][k] for k in thin},
            **cost.as_dict(), "bpp": cost.area_bytes * 8 / (w * h)}, render


def measure_photo(folder, name, classes, crop, variants, check, base=DEFAULT):
    """Every variant and the peers on one photo; ``base``: the options of ``convert_photo``."""
    photo, mask = load(folder, name, crop)
    h, w = photo.shape[:2]
    mpx = w * h / 1e6
    thin = THIN[folder]
    clock, cpu = Stopwatch(), time.process_time()
    res = convert_photo(photo, base, progress=clock)
    secs, cpu = time.perf_counter() - clock.start, time.process_time() - cpu
    shared = clock.first(50)
    choice = clock.first(85) - shared if base.cell == "auto" else 0.0
    s_cls = class_iou_scores(res.labels, mask, classes)
    row = {"folder": folder, "photo": name, "size": [w, h], "mpx": round(mpx, 3),
           "classes": classes, "crop": crop, "load_average": os.getloadavg()[0],
           "miou_cls": round(s_cls["miou"], 4),
           "thin_cls": {thin[k]: s_cls["iou"][k] for k in thin},
           "seconds_classify_themes": round(shared, 2), "seconds_cell_choice": round(choice, 2),
           "cpu_seconds_convert": round(cpu, 2),
           "variants": {}}
    renders = {}
    for vname, opts in variants.items():
        t = time.perf_counter()
        if vname == "default":
            (project, calm), seconds = (res.project, res.mapping.calm), secs
        else:
            # The defaults' cell choice, unless the variant's grids differ (keep_specks).
            reuse = opts.cell == "auto" and opts.keep_specks == base.keep_specks
            cell = res.choice.cell[0] if reuse else opts.cell
            project, calm = variant_project(photo, res, opts, cell)
            seconds = time.perf_counter() - t + shared + (choice if reuse else 0.0)
        if check and vname == "default":
            again, _ = variant_project(photo, res, opts, res.choice.cell[0])
            same_map = (again.colour_map is None) == (project.colour_map is None) and (
                again.colour_map is None
                or np.array_equal(again.colour_map.pixels, project.colour_map.pixels))
            if not (np.array_equal(again.grid.indices, project.grid.indices) and same_map):
                raise SystemExit("variant composition differs from convert_photo: fix the bench")
        scores, renders[vname] = score_texture(photo, mask, classes, thin, project,
                                               opts.boundary, calm)
        scores.update(seconds=round(seconds, 2), mpx_per_s=round(mpx / seconds, 3),
                      miou_ratio=round(scores["miou_tex"] / max(row["miou_cls"], 1e-9), 4))
        row["variants"][vname] = scores
    area = row["variants"]["default"]["area_bytes"]
    row["peers_at_default_bytes"] = score_peers(photo, area)
    if len(variants) > 1:
        row["peers_ladder"] = {str(b): score_peers(photo, int(b * w * h / 8))
                               for b in LADDER_BPP}
    return row, photo, renders["default"]


def _mean(values):
    values = [v for v in values if v is not None]
    return round(float(np.mean(values)), 4) if values else None


def summarise(rows):
    """Means over photos per variant and per peer; the goals of issue 13."""
    out = {"variants": {}, "peers_at_default_bytes": {}, "peers_ladder": {}}
    for v in rows[0]["variants"]:
        vs = [r["variants"][v] for r in rows]
        m = {k: _mean([x[k] for x in vs]) for k in
             ("dE8", "detail", "miou_tex", "miou_ratio", "bpp", "area_bytes", "grid_bytes",
              "colour_map_bytes", "theme_bytes", "seconds", "cell")}
        m["mpx_per_s"] = round(sum(r["mpx"] for r in rows) / sum(x["seconds"] for x in vs), 3)
        m["thin_tex"] = {f"{r['folder']}:{k}": None for r in rows
                         for k in THIN[r["folder"]].values()}
        for key in m["thin_tex"]:
            folder, k = key.split(":")
            m["thin_tex"][key] = _mean([r["variants"][v]["thin_tex"][k] for r in rows
                                        if r["folder"] == folder])
        out["variants"][v] = m
    out["miou_cls"] = _mean([r["miou_cls"] for r in rows])
    out["thin_cls"] = {key: _mean([r["thin_cls"][key.split(":")[1]] for r in rows
                                   if r["folder"] == key.split(":")[0]])
                       for key in out["variants"]["default"]["thin_tex"]}
    for c in CODECS:
        fits = [r["peers_at_default_bytes"][c.name] for r in rows]
        out["peers_at_default_bytes"][c.name] = {
            "fits": sum(f is not None for f in fits), "of": len(fits),
            **{k: _mean([f[k] for f in fits if f]) for k in ("dE8", "detail", "bytes")}}
        if "peers_ladder" in rows[0]:
            out["peers_ladder"][c.name] = {}
            for b in LADDER_BPP:
                fits = [r["peers_ladder"][str(b)][c.name] for r in rows]
                out["peers_ladder"][c.name][str(b)] = {
                    "fits": sum(f is not None for f in fits), "of": len(fits),
                    **{k: _mean([f[k] for f in fits if f]) for k in ("dE8", "detail")}}
    out["goals"] = goals(rows, out["variants"]["default"])
    return out


def goals(rows, mean):
    """Whether each goal of issue 13 holds for the defaults, with the photos that miss it."""
    lo, hi = GOALS["detail"]
    low_ratio = [r["photo"] for r in rows
                 if r["variants"]["default"]["miou_ratio"] < GOALS["miou_ratio"]]
    detail_out = [r["photo"] for r in rows if not lo <= r["variants"]["default"]["detail"] <= hi]
    beaten = []
    for r in rows:
        d = r["variants"]["default"]
        for codec, p in r["peers_at_default_bytes"].items():
            if p is not None and (d["detail"] <= p["detail"]
                                  or d["dE8"] > p["dE8"] + GOALS["dE8_over_peer"]):
                beaten.append(f"{r['photo']}:{codec}")
    mid = [r for r in rows if 1.0 <= r["mpx"] <= 2.0]
    slow = max((r["variants"]["default"]["seconds"] for r in mid), default=None)
    return {
        "mean_dE8<=3.0": mean["dE8"] <= GOALS["mean_dE8"],
        "mean_detail_in_0.8..1.25": lo <= mean["detail"] <= hi,
        "photos_detail_outside_0.8..1.25": detail_out,
        "miou_ratio>=0.9_every_photo": not low_ratio, "photos_miou_ratio<0.9": low_ratio,
        "beats_peers_every_photo": not beaten, "photos_codecs_not_beaten": beaten,
        "slowest_1-2Mpx_convert_s": slow,
        "convert_1-2Mpx<5s": None if slow is None else slow < GOALS["convert_seconds"],
    }


def side_by_side(photo, render, path):
    """photo | texture, about PICTURE_WIDTH wide, JPEG quality 85."""
    half = (PICTURE_WIDTH - 8) // 2
    size = (half, max(1, round(photo.shape[0] * half / photo.shape[1])))
    parts = [cv2.resize(a, size, interpolation=cv2.INTER_AREA) for a in (photo, render)]
    gap = np.full((size[1], 8, 3), 255, np.uint8)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_image(path, np.concatenate([parts[0], gap, parts[1]], axis=1), compression="jpeg:85")


def run_variants(sets, quick, log):
    rows = []
    for i, (folder, name, classes, crop) in enumerate(sets):
        row, photo, render = measure_photo(folder, name, classes, crop, VARIANTS, check=i == 0)
        rows.append(row)
        d = row["variants"]["default"]
        log(f"  {name}: dE8 {d['dE8']} detail {d['detail']} mIoU {d['miou_tex']}/"
            f"{row['miou_cls']} {d['area_bytes']} B {d['seconds']} s")
    sample = None
    if not quick and SAMPLE.is_file():
        photo = np.ascontiguousarray(read_image(SAMPLE)[:, :, :3])
        t = time.perf_counter()
        res = convert_photo(photo)
        secs = time.perf_counter() - t
        h, w = photo.shape[:2]
        render = render_project(res.project, (0, 0, w, h))
        sample = {"seconds": round(secs, 2), "dE8": round(colour_error(render, photo), 3),
                  "detail": round(detail_ratio(render, photo), 3),
                  **texture_cost(res.project).as_dict(), "cell": res.project.grid.cell[0]}
    return {"photos": rows, "summary": summarise(rows), "sample": sample}


def run_defaults(sets, log, options=DEFAULT):
    """``options`` as convert's defaults: texture and peers at its bytes on every photo."""
    rows = []
    for folder, name, classes, crop in sets:
        row, _, _ = measure_photo(folder, name, classes, crop, {"default": options},
                                  check=False, base=options)
        rows.append(row)
        d = row["variants"]["default"]
        log(f"  {name}: dE8 {d['dE8']} detail {d['detail']} mIoU {d['miou_tex']}/"
            f"{row['miou_cls']} {d['area_bytes']} B {d['seconds']} s")
    return {"photos": rows, "summary": summarise(rows)}


def structure_variants(photo):
    """Issue 34's textures of one photo: the old default (whole themes, dE8 target 2) and
    the budget's at :data:`BUDGETS`, all from one classification, theme cut and cell choice,
    as ``convert_photo`` makes them; ``{name: (project, seconds)}``."""
    t = time.perf_counter()
    result, _ = classify_photo(photo)
    whole = assign_themes(photo, result.labels, result.classes)
    theme_labels = apply_lut(result.labels, whole.lut)
    detail, twin_labels = detail_mapping(photo, theme_labels, whole)
    choice = choose_cell_size(theme_labels, DEFAULT.target_agreement,
                              candidates=DEFAULT.candidates, class_target=DEFAULT.class_target,
                              full_curve=False, keep_specks=False)
    shared = time.perf_counter() - t
    h, w = photo.shape[:2]
    out = {}
    for name, mapping, cmap in (
            ("old default", whole, ColourMapOptions(target=2.0)),
            *((f"budget {b}", detail, ColourMapOptions(budget=b)) for b in BUDGETS),
            ("budget 0.04, whole themes", whole, ColourMapOptions(budget=0.04))):
        t = time.perf_counter()
        cap = grid_budget(cmap, h * w)
        cell = choice if cap is None else cell_within_budget(
            theme_labels, choice, DEFAULT.candidates, cap, keep_specks=False)
        made = grid_and_colour(photo, theme_labels, mapping, cell="auto", choice=cell,
                               colour_map=cmap, render=RenderOptions(boundary=DEFAULT.boundary),
                               keep_specks=False,
                               twin_labels=twin_labels if mapping is detail else None)
        project = ThematicTexture(made.grid, made.mapping.library, {"photo_size": [w, h]},
                                  colour_map=made.colour.colour_map)
        out[name] = (project, shared + time.perf_counter() - t)
    return out


def peer_picture(photo, point, codec):
    """The photo through ``codec`` at one of :func:`best_peers`' points, back at full size."""
    make, decode = PEER_MAKERS[codec]
    h, w = photo.shape[:2]
    small = cv2.resize(photo, (point["width"], max(1, round(h * point["width"] / w))),
                       interpolation=cv2.INTER_AREA)
    back = np.asarray(decode(make(point["quality"])(small)))[:, :, :3]
    return cv2.resize(back, (w, h), interpolation=cv2.INTER_CUBIC)


def crop_strip(parts, x, y, path):
    """1:1 crops side by side (photo | texture | AVIF | ...), 8 white pixels apart, PNG."""
    s = CROP_SIDE
    gap = np.full((s, 8, 3), 255, np.uint8)
    row = [p for part in parts for p in (np.ascontiguousarray(part[y:y + s, x:x + s]), gap)]
    path.parent.mkdir(parents=True, exist_ok=True)
    write_image(path, np.concatenate(row[:-1], axis=1))


def run_structure(log):
    """Issue 34: every variant of :func:`structure_variants` and JPEG / AVIF at its bytes."""
    rows, keep = [], {}
    pictures = {v: k for k, v in PICTURES}
    for folder, name in STRUCTURE_PHOTOS:
        photo = (np.ascontiguousarray(read_image(SAMPLE)[:, :, :3]) if folder == "sample"
                 else load(folder, name, None)[0])
        h, w = photo.shape[:2]
        row = {"photo": name, "size": [w, h], "variants": {}}
        made = structure_variants(photo)
        if folder == "sample":
            # The composition is convert_photo's: the same grid, themes and colour map.
            direct = convert_photo(photo).project
            ours = made[f"budget {DEFAULT.colour_map.budget}"][0]
            if not (np.array_equal(direct.grid.indices, ours.grid.indices) and np.array_equal(
                    direct.colour_map.pixels, ours.colour_map.pixels)
                    and len(direct.library) == len(ours.library) and all(
                    np.array_equal(a.texture, b.texture)
                    for a, b in zip(direct.library, ours.library, strict=False))):
                raise SystemExit("structure variants differ from convert_photo: fix the bench")
        for vname, (project, secs) in made.items():
            render = render_project(project, (0, 0, w, h),
                                    options=RenderOptions(boundary=DEFAULT.boundary))
            cost = texture_cost(project)
            peers = best_peers(photo, cost.area_bytes)
            row["variants"][vname] = {
                **score_image(render, photo), **cost.as_dict(),
                "bpp": round(cost.area_bytes * 8 / (w * h), 4), "seconds": round(secs, 2),
                "map_scale": project.colour_map.coded_scale,
                "map_upsample": project.colour_map.upsample, "cell": project.grid.cell[0],
                "peers": peers}
            v = row["variants"][vname]
            log(f"  {name} {vname}: dE8 {v['dE8']} s4 {v['s4']} s8 {v['s8']} detail "
                f"{v['detail']} placement {v['placement']} {v['area_bytes']} B | avif " +
                " ".join(f"{k} {peers['avif'][k]}" for k in AXES))
            if folder == "sample":
                keep[vname] = (photo, render, peers)
            if vname == f"budget {DEFAULT.colour_map.budget}" and name in pictures:
                side_by_side(photo, render, DOCS / f"{pictures[name]}.jpg")
        rows.append(row)
    # 1:1 crops of the sample: photo | old default | texture | AVIF at the texture's bytes.
    photo, render, peers = keep["budget 0.04"]
    avif = peer_picture(photo, max(peers["avif"]["points"], key=lambda p: p["s4"]), "avif")
    old = keep["old default"][1]
    for crop, _, x, y in CROPS:
        crop_strip([photo, old, render, avif], x, y, DOCS / f"{crop}.png")
    return {"photos": rows, "summary": summarise_structure(rows),
            "crops": "photo | old default | texture (budget 0.04) | AVIF at the texture's bytes"}


def summarise_structure(rows):
    """Means over photos of every variant and of its peers; the goals of issue 34 per photo."""
    out = {}
    for v in rows[0]["variants"]:
        vs = [r["variants"][v] for r in rows]
        m = {k: _mean([x[k] for x in vs]) for k in (*AXES, "bpp", "area_bytes")}
        m["peers"] = {c: {k: _mean([x["peers"][c][k] for x in vs if x["peers"][c]])
                          for k in AXES} for c in PEER_MAKERS}
        lo, hi = GOALS["detail"]
        m["photos_meeting_goal"] = sum(
            all(x[k] >= max(p[k] for p in x["peers"].values() if p) for k in ("s4", "s8"))
            and x["dE8"] <= min(p["dE8"] for p in x["peers"].values() if p)
            and lo <= x["detail"] <= hi for x in vs)
        out[v] = m
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", help=f"{', '.join(PARTS)} (default: all)")
    ap.add_argument("--quick", action="store_true", help="two photos, no pictures")
    ap.add_argument("--chart", action="store_true", help="redraw the chart from fidelity.json")
    args = ap.parse_args()
    path = OUT / "fidelity.json"
    if args.chart:
        return chart(json.loads(path.read_text()), path.with_suffix(".png"), GOALS)
    parts = args.parts or list(PARTS)
    if set(parts) - set(PARTS):
        ap.error(f"unknown part in {parts}: use {', '.join(PARTS)}")
    if not DATA.is_dir():
        raise SystemExit(f"{DATA} not found: this benchmark needs ../shared/data")
    result = json.loads(path.read_text()) if path.is_file() and not args.quick else {}
    result["inputs"] = {
        "variants": {k: asdict(v) for k, v in VARIANTS.items()},
        "trials": {k: asdict(v) for k, v in TRIALS.items()},
        "codecs": {c.name: c.quality for c in CODECS}, "ladder_bpp": LADDER_BPP,
        "thin_classes": THIN, "goals": GOALS, "cpus": os.cpu_count()}
    # Numba kernels compile on first use: warm them on a crop, not part of the timings.
    photo, _ = load("dubai", "image_part_004t5.jpg")
    convert_photo(photo[:128, :128], ConvertOptions(cell=8))
    def log(msg):
        print(msg, flush=True)

    for part in parts:
        t = time.perf_counter()
        load0 = os.getloadavg()[0]
        if part == "structure":
            result["structure"] = run_structure(log)
            result["structure"]["run"] = {"seconds": round(time.perf_counter() - t, 1)}
            log(json.dumps(result["structure"]["summary"], indent=1))
            continue
        if part == "variants":
            sets = scribble_sets()[:2] if args.quick else scribble_sets()
            result["variants"] = run_variants(sets, args.quick, log)
        elif part in ("defaults54", "trials54"):
            sets = dubai_all()[:2] if args.quick else dubai_all()
            options = DEFAULT if part == "defaults54" else TRIALS[BEST_TRIAL]
            result[part] = run_defaults(sets, log, options)
            result[part]["options"] = "defaults" if part == "defaults54" else BEST_TRIAL
        else:
            sets = scribble_sets()[:2] if args.quick else scribble_sets()
            result["trials"] = {}
            for trial, options in TRIALS.items():
                log(f" trial {trial}")
                result["trials"][trial] = run_defaults(sets, log, options)
        result[part]["run"] = {"seconds": round(time.perf_counter() - t, 1),
                               "load_average_start_end": [load0, os.getloadavg()[0]]}
        summaries = ([result[part]["summary"]] if part != "trials" else
                     [t["summary"] for t in result[part].values() if "summary" in t])
        log(f"{part}: {result[part]['run']}")
        for summary in summaries:
            log(json.dumps(summary["goals"]))
    out = Path(tempfile.gettempdir()) / "fidelity_quick.json" if args.quick else path
    out.write_text(json.dumps(result, indent=1, default=str))
    if "variants" in result or "structure" in result:
        chart(result, out.with_suffix(".png"), GOALS)
    log(f"wrote {out}")


if __name__ == "__main__":
    main()
