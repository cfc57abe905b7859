"""Part "corrections" of ``bench_classify.py``: scribbles painted in two rounds.

One-shot scribbles (part "scribbles") spend the whole budget blind. An editor
user paints, looks at the labels and the confidence map, and adds strokes where
the result is wrong. Same budget (<= 0.8% of the pixels), same strokes
(30 x 3 px inside eroded true-class regions), same 16 photos, spent as:

  round 1   :func:`simulate_scribbles` with half the budget (rng seeded as the
            one-shot part); train, classify the whole photo;
  round 2   the rest of the budget as correction strokes
            (:func:`simulate_corrections`), labelled with the true class, placed
            by one of two variants:
              ``corrections``     on the largest misclassified regions (the user
                                  sees the errors);
              ``low-confidence``  on the largest regions of the lowest
                                  ``LOW_CONFIDENCE_SHARE`` of the confidence map
                                  (no ground truth chooses where: the prompt the
                                  app can offer, active-learning style);
  then retrain on all strokes and score as the one-shot part does.
Each method corrects its own errors: rf-default (the library default), rf-noprior
(rf-default without the prior correction, which assumes class-balanced strokes --
correction strokes are not), rf-keepprior (rf-default retrained on round 2
keeping the prior correction estimated from round 1; its one-shot and round-1 rows
are rf-default's) and the ilastik recipe (scored on 50,000 random pixels
per photo as in part "scribbles"; round 1 is predicted on every pixel to place
round 2).
``round1`` rows are the half-budget result the corrections start from; ``one-shot``
rows are the peer: the whole budget by :func:`simulate_scribbles`, drawn in the same
run from generators seeded as round 1's. Every row is the mean of ``REPEATS``
independent draws of the strokes (per-repeat figures kept: single draws vary by
several hundredths of mIoU).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from classify_eval import (
    confusion,
    draw_rows,
    draw_seeds,
    scores,
    simulate_corrections,
    simulate_scribbles,
)

#: share of the photo's pixels, lowest confidence first, the app highlights
LOW_CONFIDENCE_SHARE = 0.10
#: total scribble budget, share of the photo's pixels (as part "scribbles")
BUDGET = 0.008
#: rf-default whose round 2 keeps round 1's prior correction (see _keep_prior)
KEEP = "rf-keepprior"
VARIANTS = ("one-shot", "round1", "corrections", "low-confidence")
#: independent draws of all strokes (results are means; the spread is in the rows)
REPEATS = 3


def _round2(mask, classes, rng, scr1, labels, confidence):
    """Round-2 strokes of both variants -> {variant: all strokes (H, W) uint8}."""
    valid = np.isin(mask, classes)
    rest = int(BUDGET * mask.size) - int((scr1 > 0).sum())
    low = confidence <= np.quantile(confidence[valid], LOW_CONFIDENCE_SHARE)
    out = {}
    for variant, target in (("corrections", (labels != mask) & valid),
                            ("low-confidence", low & valid)):
        scr2 = simulate_corrections(mask, classes, rng, target, rest, existing=scr1)
        out[variant] = np.where(scr1 > 0, scr1, scr2)
    return out


def corrections(log):
    """The two-round scribble protocol (rf-default, rf-noprior, rf-keepprior, ilastik) -> rows."""
    import bench_classify as bench

    # Per repeat: strokes of round 1 and of the one-shot peer from generators seeded
    # alike (repeat 0 as part "scribbles"), round-2 seeds from a third.
    seed0 = draw_seeds(bench.RNG_SEED + 1, REPEATS)
    round1_rng = [np.random.default_rng(s) for s in seed0]
    oneshot_rng = [np.random.default_rng(s) for s in seed0]
    seeds = np.random.default_rng(bench.RNG_SEED + 2)
    sets = bench.scribble_sets()
    forests = {"rf-default": bench.METHODS["rf-default"],
               "rf-noprior": bench.SCRIBBLE_METHODS["rf-noprior"]}
    cms = {(m, v): [{} for _ in range(REPEATS)] for m in (*forests, KEEP, "ilastik")
           for v in VARIANTS}
    coverage = {v: {} for v in VARIANTS}
    for folder, name, classes, crop in sets:
        photo, mask = bench.load(folder, name, crop)
        feats, secs = bench.ilastik_features(photo)
        for r in range(REPEATS):
            strokes = {"one-shot": simulate_scribbles(mask, classes, oneshot_rng[r], BUDGET),
                       "round1": simulate_scribbles(mask, classes, round1_rng[r], BUDGET / 2)}
            scr1 = strokes["round1"]
            # Every method's round 2 draws the same random numbers (fair comparison).
            seed = int(seeds.integers(2**32))
            for m, opts in forests.items():
                res = bench._train_one(photo, strokes["one-shot"], opts).predict(photo)
                cms[m, "one-shot"][r][name] = confusion(mask, res.labels, classes)
                # Round 1, then each variant's round 2 from its result.
                first = bench._train_one(photo, scr1, opts)
                res = first.predict(photo)
                cms[m, "round1"][r][name] = confusion(mask, res.labels, classes)
                for variant, scr in _round2(mask, classes, np.random.default_rng(seed), scr1,
                                            res.labels, res.confidence).items():
                    final = bench._train_one(photo, scr, opts).predict(photo)
                    cms[m, variant][r][name] = confusion(mask, final.labels, classes)
                    if m != "rf-default":
                        continue
                    strokes[variant] = scr
                    # rf-keepprior: the same strokes, round 1's prior kept.
                    final = _keep_prior(bench, photo, scr, first).predict(photo)
                    cms[KEEP, variant][r][name] = confusion(mask, final.labels, classes)
                if m == "rf-default":
                    # Before round 2 rf-keepprior is rf-default.
                    for v in ("one-shot", "round1"):
                        cms[KEEP, v][r][name] = cms[m, v][r][name]
            # ilastik: every pixel's votes of round 1 place round 2.
            model = _ilastik_model(bench, feats, scr1)
            probs = model.probabilities(feats)
            labels = np.asarray(model.classes, np.uint8)[probs.argmax(2)]
            scored = {"one-shot": _ilastik_model(bench, feats, strokes["one-shot"]),
                      "round1": model}
            for variant, scr in _round2(mask, classes, np.random.default_rng(seed), scr1,
                                        labels, probs.max(2)).items():
                scored[variant] = _ilastik_model(bench, feats, scr)
            del probs, labels
            # Every variant scored on the same random pixels.
            for variant, model in scored.items():
                pick = np.random.default_rng(seed + 1)
                cms["ilastik", variant][r][name], _ = bench.ilastik_predict(
                    model, feats, mask, classes, pick, secs)
            for v, scr in strokes.items():
                coverage[v][name] = coverage[v].get(name, 0.0) + float((scr > 0).mean()) / REPEATS
        del feats
        log(f"  corrections {name}: " + ", ".join(
            f"{m} {v} {np.mean([scores(c[name], classes)['miou'] for c in cms[m, v]]):.3f}"
            for m, v in cms))
    out = {"repeats": REPEATS, "coverage": coverage,
           "low_confidence_share": LOW_CONFIDENCE_SHARE}
    for (m, v), reps in cms.items():
        out.setdefault(m, {})[v] = draw_rows(reps, sets)
    return out


def _keep_prior(bench, photo, scr, first):
    """Retrain on all strokes, keeping the prior correction estimated in round 1.

    The prior correction (core/classify/prior.py) assumes blind, class-balanced
    strokes; correction strokes are not, so the class weights of the round-1
    model are kept (a class new in round 2 weighs 1) instead of re-estimated.
    """
    model = bench._train_one(photo, scr, replace(first.options, prior_power=0.0))
    if first.class_weights is not None:
        old = dict(zip(first.classes, first.class_weights, strict=True))
        model.class_weights = tuple(old.get(c, 1.0) for c in model.classes)
    return model


def _ilastik_model(bench, feats, scr):
    sel = scr.ravel() > 0
    x = feats.reshape(-1, feats.shape[2])[sel]
    y = scr.ravel()[sel].astype(np.int32)
    return bench.ilastik_model(x, y)
