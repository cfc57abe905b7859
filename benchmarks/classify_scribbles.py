"""Part "scribbles" of ``bench_classify.py``: one-shot strokes, several draws and budgets.

Short strokes (3 px wide, 30 px long) inside eroded class regions, at most
``BUDGET`` (0.8%) of the photo's pixels, train and test on the same photo, 16
photos (:func:`bench_classify.scribble_sets`). Where the strokes fall moves a
photo's mIoU by several hundredths, more than most differences between
methods, so every method is scored on the same ``DRAWS`` independent draws of
the strokes, drawn from the generators of the one-shot rows of part
"corrections" (so rf-default's rows agree between the two parts). A row's
``mean_miou_over_photos`` is the mean over the draws of the mean over the 16
photos; the per-draw means are kept.

Budget curve (row group ``scribbles_budget``): rf-default and the ilastik recipe
at ``BUDGETS`` of the pixels (as many draws, the strokes drawn afresh for each
budget), to show what more paint buys.
"""

from __future__ import annotations

import time

import numpy as np
from classify_eval import confusion, draw_rows, draw_seeds, simulate_scribbles

#: one-shot scribble budget, share of the photo's pixels (the issue allows <= 1%)
BUDGET = 0.008
#: independent draws of the strokes
DRAWS = 3
#: budgets of the budget curve (BUDGET's point is the main rows)
BUDGETS = (0.0025, 0.005, 0.008, 0.01)
#: methods of the budget curve
CURVE_METHODS = ("rf-default", "ilastik")


def scribbles(log):
    """Every method on ``DRAWS`` draws at ``BUDGET`` -> rows (and the budget curve)."""
    import bench_classify as bench

    sets = bench.scribble_sets()
    methods = {"rf-default": bench.METHODS["rf-default"], **bench.SCRIBBLE_METHODS,
               **{m: o for m, o in bench.METHODS.items() if m != "rf-default"}}
    names = [*methods, "ilastik", "kmeans-colour"]
    # One generator per (budget, draw), each consumed photo after photo.
    rngs = {(b, d): np.random.default_rng(s if b == BUDGET else [*np.atleast_1d(s), int(b * 1e4)])
            for b in BUDGETS for d, s in enumerate(draw_seeds(bench.RNG_SEED + 1, DRAWS))}
    cms = {m: [{} for _ in range(DRAWS)] for m in names}
    curve = {(m, b): [{} for _ in range(DRAWS)] for m in CURVE_METHODS for b in BUDGETS}
    speed = {m: [0.0, 0.0] for m in names}
    coverage = {}
    for folder, name, classes, crop in sets:
        photo, mask = bench.load(folder, name, crop)
        feats, secs = bench.ilastik_features(photo)
        for d in range(DRAWS):
            for b in BUDGETS:
                scr = simulate_scribbles(mask, classes, rngs[b, d], b)
                coverage[name, b] = max(coverage.get((name, b), 0.0), float((scr > 0).mean()))
                run = methods if b == BUDGET else {
                    m: methods[m] for m in CURVE_METHODS if m in methods}
                for m, opts in run.items():
                    model = bench._train_one(photo, scr, opts)
                    t = time.perf_counter()
                    res = model.predict(photo)
                    if b == BUDGET:
                        speed[m][1] += time.perf_counter() - t
                        speed[m][0] += mask.size
                        cms[m][d][name] = confusion(mask, res.labels, classes)
                    if m in CURVE_METHODS:
                        curve[m, b][d][name] = confusion(mask, res.labels, classes)
                # The ilastik recipe, scored on the same random pixels for every budget.
                sel = scr.ravel() > 0
                x, y = feats.reshape(-1, feats.shape[2])[sel], scr.ravel()[sel].astype(np.int32)
                model = bench.ilastik_model(x, y)
                pick = np.random.default_rng([bench.RNG_SEED + 3, d])
                cm, mpxs = bench.ilastik_predict(model, feats, mask, classes, pick, secs)
                curve["ilastik", b][d][name] = cm
                if b != BUDGET:
                    continue
                cms["ilastik"][d][name] = cm
                speed["ilastik"][0] += mask.size
                speed["ilastik"][1] += mask.size / mpxs / 1e6
                cm, mpxs = bench.kmeans_predict(photo, mask, classes, scr)
                cms["kmeans-colour"][d][name] = cm
                speed["kmeans-colour"][0] += mask.size
                speed["kmeans-colour"][1] += mask.size / mpxs / 1e6
        del feats
        log(f"  scribbles {name}: {coverage[name, BUDGET]:.2%} of pixels at most, "
            f"rf-default {draw_rows(cms['rf-default'], sets)['miou_per_photo'][name]:.3f}")
    out = {"draws": DRAWS, "budget": BUDGET,
           "coverage": {n: round(c, 5) for (n, b), c in coverage.items() if b == BUDGET}}
    for m in names:
        mpxs = speed[m][0] / max(speed[m][1], 1e-9) / 1e6
        out[m] = {**draw_rows(cms[m], sets), "mpx_per_s": mpxs}
    budget = {"budgets": list(BUDGETS), "draws": DRAWS,
              "max_coverage": {str(b): max(c for (_n, bb), c in coverage.items() if bb == b)
                               for b in BUDGETS}}
    for (m, b), reps in curve.items():
        budget.setdefault(m, {})[str(b)] = draw_rows(reps, sets)
    return out, budget
