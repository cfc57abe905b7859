"""Part "aerial" of ``bench_classify.py``: the shipped model on photos of other datasets.

The ``aerial-forest`` model (``models/``, trained on all 54 CC0 Dubai photos by
``models/train_aerial.py``) classifies LoveDA (2 photos), ISPRS Potsdam and
DeepGlobe 6399 (whole photos) with no labels of theirs at all. Each dataset's
legend and the model's five classes are mapped to the classes they share
(``COMMON``: e.g. DeepGlobe's "urban" is our building or road, LoveDA's forest
and agriculture our vegetation; classes with no counterpart, such as LoveDA's
"background" or Potsdam's cars and clutter, are not scored) and mIoU is taken
over the shared classes present in the photo's truth.

Rows, all in the same run:
  aerial            the shipped model (trained on 54 photos: no adaptation);
  aerial-adapt      the same forest adapting to each photo (core/classify/adapt.py);
  scribbles         rf-default trained on 0.8% strokes of the photo itself, its own
                    legend (classify_scribbles.py's first draw), then mapped the same
                    way: a peer that was shown the photo's own classes;
  kmeans-oracle     k-means on colour (K = shared classes present), each cluster named
                    by its majority true class: what colour clusters reach at best.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from classify_eval import scores, simulate_scribbles
from terratheme.core.classify import Classifier, SupervisedOptions, train_classifier
from terratheme.core.classify.shipped import resolve_model

#: dataset -> (photos, {dataset class: shared name}, {model class: shared name})
AERIAL = {1: "building", 2: "land", 3: "road", 4: "vegetation", 5: "water"}
COMMON = {
    "loveda": (("loveda_0.png", "loveda_1.png"),
               {2: "building", 3: "road", 4: "water", 5: "land", 6: "vegetation",
                7: "vegetation"}, AERIAL),
    "potsdam": (("potsdam_2_10_0_0_512_512.png",),
                {1: "road", 2: "building", 3: "vegetation", 4: "vegetation"},
                {**AERIAL, 2: "land"}),
    "deepglobe": (("6399_sat.jpg",),
                  {1: "urban", 2: "vegetation", 3: "vegetation", 4: "vegetation", 5: "water",
                   6: "land"},
                  {1: "urban", 2: "land", 3: "urban", 4: "vegetation", 5: "water"}),
}
SHARED = ("building", "road", "urban", "land", "vegetation", "water")
#: scribble budget of the peer (as part "scribbles")
SCRIBBLE_BUDGET = 0.008


def _lut(mapping: dict[int, str]) -> np.ndarray:
    """Class value -> index in SHARED + 1 (0 = not scored)."""
    lut = np.zeros(256, np.uint8)
    for k, name in mapping.items():
        lut[k] = SHARED.index(name) + 1
    return lut


def shared_scores(truth: np.ndarray, pred: np.ndarray, truth_map, pred_map) -> dict:
    """mIoU over the shared classes present in the truth.

    Pixels whose truth has no shared class are skipped; a prediction of a class
    the truth lacks (or of no shared class) is an error of its true class.
    """
    t, p = _lut(truth_map)[truth].ravel(), _lut(pred_map)[pred].ravel()
    present = [int(v) for v in np.unique(t) if v > 0]
    col = np.full(256, len(present), np.int64)
    col[present] = np.arange(len(present))
    row = col[t[t > 0]]
    c = len(present)
    cm = np.bincount(row * (c + 1) + col[p[t > 0]], minlength=c * (c + 1)).reshape(c, c + 1)
    tp = np.diag(cm[:, :c]).astype(float)
    iou = tp / np.maximum(cm.sum(1) + cm[:, :c].sum(0) - tp, 1)
    return {"miou": float(iou.mean()), "oa": float(tp.sum() / max(cm.sum(), 1)),
            "iou": {SHARED[k - 1]: round(float(v), 4) for k, v in zip(present, iou, strict=True)}}


def aerial(log):
    """The shipped model and its peers on LoveDA, Potsdam and DeepGlobe -> rows."""
    import bench_classify as bench

    path, names = resolve_model("aerial-forest")
    model = Classifier.load(path)
    adapting = Classifier(model.forest, model.classes, replace(model.options, adapt=True))
    rows = {m: {} for m in ("aerial", "aerial-adapt", "scribbles", "kmeans-oracle")}
    speed = {m: [0, 0.0] for m in rows}
    for folder, (photos, truth_map, pred_map) in COMMON.items():
        for name in photos:
            photo, mask = bench.load(folder, name)
            for m, clf in (("aerial", model), ("aerial-adapt", adapting)):
                t = time.perf_counter()
                res = clf.predict(photo)
                speed[m][1] += time.perf_counter() - t
                speed[m][0] += mask.size
                rows[m][name] = shared_scores(mask, res.labels, truth_map, pred_map)
            own = sorted(set(np.unique(mask).tolist()) & set(truth_map))
            scr = simulate_scribbles(mask, own, np.random.default_rng(bench.RNG_SEED + 1),
                                     SCRIBBLE_BUDGET)
            t = time.perf_counter()
            res = train_classifier([(photo, scr)], SupervisedOptions()).predict(photo)
            speed["scribbles"][1] += time.perf_counter() - t
            speed["scribbles"][0] += mask.size
            identity = {k: truth_map[k] for k in own}
            rows["scribbles"][name] = shared_scores(mask, res.labels, truth_map, identity)
            # k-means, clusters named by the truth in the shared classes.
            shared = _lut(truth_map)[mask]
            present = sorted(int(v) for v in np.unique(shared) if v > 0)
            cm, mpxs = bench.kmeans_predict(photo, shared, present, shared)
            speed["kmeans-oracle"][0] += mask.size
            speed["kmeans-oracle"][1] += mask.size / mpxs / 1e6
            out = scores(cm, [SHARED[k - 1] for k in present])
            rows["kmeans-oracle"][name] = {"miou": out["miou"], "oa": out["oa"],
                                           "iou": out["iou"]}
            log(f"  aerial {name}: model {rows['aerial'][name]['miou']:.3f} "
                f"(adapting {rows['aerial-adapt'][name]['miou']:.3f}), scribbles "
                f"{rows['scribbles'][name]['miou']:.3f}, k-means oracle "
                f"{rows['kmeans-oracle'][name]['miou']:.3f}")
    out = {"model": str(path.name), "model_bytes": path.stat().st_size,
           "class_names": {str(k): v for k, v in (names or {}).items()}}
    for m, per in rows.items():
        out[m] = {"per_photo": per,
                  "mean_miou": float(np.mean([r["miou"] for r in per.values()])),
                  "mpx_per_s": speed[m][0] / max(speed[m][1], 1e-9) / 1e6}
    return out
