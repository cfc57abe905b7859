"""Classification accuracy and speed on the real photos in ../shared/data.

Run: ``.venv/bin/python benchmarks/bench_classify.py [scribbles] [corrections]
[across_tiles] [one_per_tile] [train_cost] [aerial] [memory]`` (all by default, about
30-40 minutes on 2 busy cores;
naming parts reruns only those and keeps the others from the last classify.json;
``--scribbles-only`` = ``scribbles corrections``, for iterating on the scribble parts).
Writes ``benchmarks/results/classify.json`` and ``classify.png``.

(a) across tiles: Dubai, leave one satellite tile out (train on the photos of
    five tiles, test on every photo of the sixth), classes 1-5 (6, 7 ignored);
(b) scribbles: short strokes (3 px wide, 30 px long) inside eroded class
    regions, <= 0.8% of the photo's pixels, train and test on the same photo:
    12 Dubai photos, 2 LoveDA, 1 Potsdam, DeepGlobe 6399 (top-left 1536 crop);
    every row the mean of 3 independent draws of the strokes, plus a budget
    curve (0.25% to 1%) for rf-default and ilastik; see classify_scribbles.py.
(c) corrections (row group ``scribbles_corrections``): the same budget, photos and
    strokes painted in two rounds, round 2 where the round-1 result is wrong (or least
    confident), as an editor user does; see classify_corrections.py.
(d) one_per_tile: issue 17's protocol, train on one photo of each other tile, score
    every photo of the held-out tile; the robustness pieces one by one; see
    classify_one_per_tile.py.
(e) train_cost: train on six photos + classify a seventh (1.5 Mpx), without a cache,
    with the sample cache, with the sample and model caches, against classifying it
    alone (paired rounds, wall and CPU); see classify_train_cost.py.
(f) aerial: the shipped model (models/aerial) on LoveDA, Potsdam and DeepGlobe; see
    classify_aerial.py.

Methods, all in the same run:
  rf-default      Extra-Trees (core/classify/extra_trees.py, 50 trees, soft votes) on
                  DEFAULT features with Hessian eigenvalues and fine ridges
                  (core/classify/ridges.py, sigmas 1, 2, 4 px), 8x8 coarse pixels,
                  edge-aware confidence-weighted regularisation (Regularisation.EDGE,
                  core/classify/regularise.py) -- the library default (for (a), trained
                  on 45 photos, without test-time adaptation); for (b) also the
                  scribble defaults: prior correction at power 0.75
                  (core/classify/prior.py) and strokes grown by one ring of same-colour
                  coarse pixels (core/classify/samples.py);
  rf-adapt        (a) only: rf-default's forest adapting to each photo
                  (core/classify/adapt.py, the default for fewer than 10 photos);
  rf-noridges     rf-default without the fine ridges;
  rf-smooth       rf-default with Gaussian probability smoothing instead of EDGE;
  rf-noprior      (b) only: rf-default without the prior correction (prior_power=0);
  rf-prior1       (b) only: rf-default with the full prior correction (prior_power=1);
  rf-nogrow       (b) only: rf-default without growing the strokes (grow_colour=0);
  rf-position     (b) only: rf-default plus the coarse pixel's position in the photo
                  (FeatureOptions.position; legitimate for a model of one photo);
  rf-colour       rf-default on coarse Lab only;
  rf-scale4       DEFAULT features on 4x4 coarse pixels (same context in photo pixels);
  ilastik         the ilastik recipe (classify_peers.py): OpenCV's random forest
                  (24 trees, hard votes) on Lab + scikit-image
                  multiscale_basic_features (sigma 1..16) for every pixel, no
                  regularisation. Too slow to predict whole photos in the time
                  budget: it is trained on the same pixels and scored on 50,000
                  random labelled pixels per photo; its Mpx/s is features + votes
                  per pixel, measured. For (a) it runs on parts 001-003 of each tile
                  (18 photos), and rf-default is reported on the same subset.
  kmeans-colour   k-means on Lab. (a): 10 clusters fitted to the training tiles'
                  coarse Lab, each named by its majority class there, applied per
                  pixel to the unseen tile. (b): K = number of classes, fitted on the
                  photo, clusters named by the scribbles they hold.
  kmeans-oracle   (a) only: K-means per test photo (K = 5), clusters named by the
                  test photo's own true mask -- an upper bound colour clustering
                  cannot reach without labels, not a competitor.
"""

from __future__ import annotations

import json
import sys
import time
import tracemalloc
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from classify_aerial import aerial  # noqa: E402
from classify_chart import chart  # noqa: E402
from classify_corrections import corrections  # noqa: E402
from classify_eval import confusion, scores, simulate_scribbles  # noqa: E402
from classify_one_per_tile import one_per_tile  # noqa: E402
from classify_peers import (  # noqa: E402, F401 (classify_corrections/_scribbles read them here)
    ILASTIK_TEST_PIXELS,
    KMEANS,
    RNG_SEED,
    ColourKMeans,
    ilastik_features,
    ilastik_model,
    ilastik_predict,
    kmeans_predict,
    labelled_pixels,
    timed_votes,
)
from classify_scribbles import scribbles  # noqa: E402
from classify_train_cost import train_cost  # noqa: E402
from terratheme.core.classify import (  # noqa: E402
    Classifier,
    FeatureOptions,
    FeatureSet,
    Regularisation,
    RegulariseOptions,
    SupervisedOptions,
)
from terratheme.core.classify.supervised import _pair_samples, build_forest  # noqa: E402
from terratheme.core.io.images import read_image  # noqa: E402

DATA = REPO.parent / "shared" / "data"
OUT = REPO / "benchmarks" / "results"
#: training samples per class for (a): the ilastik recipe's forest trains on one core
ACROSS_CAP = 6000
#: clusters of the k-means-on-colour baseline trained on other tiles
KMEANS_CLUSTERS = 10
#: (a) only: rf-default's forest with the test-time adaptation
ADAPT = "rf-adapt"

METHODS = {
    "rf-default": SupervisedOptions(),
    "rf-noridges": SupervisedOptions(features=FeatureOptions(hessian=True, structure=True)),
    "rf-smooth": SupervisedOptions(regularisation=RegulariseOptions(
        method=Regularisation.SMOOTH)),
    "rf-colour": SupervisedOptions(features=FeatureOptions(feature_set=FeatureSet.COLOUR)),
    "rf-scale4": SupervisedOptions(features=FeatureOptions(
        scale=4, sigmas=(1.0, 2.0, 4.0, 8.0), hessian=True)),
}
#: methods of the scribble part only (the across-tiles part trains on full masks)
SCRIBBLE_METHODS = {
    "rf-noprior": SupervisedOptions(prior_power=0.0),
    "rf-prior1": SupervisedOptions(prior_power=1.0),
    "rf-nogrow": SupervisedOptions(grow_colour=0.0),
    "rf-position": SupervisedOptions().with_positions(),
}
def load(folder, name, crop=None):
    img = read_image(DATA / folder / "images" / name)
    mask = read_image(DATA / folder / "masks" / (Path(name).stem + ".png"))[:, :, 0]
    if crop:
        img, mask = img[:crop, :crop], mask[:crop, :crop]
    return np.ascontiguousarray(img[:, :, :3]), np.ascontiguousarray(mask)


def across_tiles(log):
    classes = [1, 2, 3, 4, 5]
    names = sorted(p.name for p in (DATA / "dubai" / "images").glob("*.jpg"))
    tile_of = {n: int(n.split("t")[-1].split(".")[0]) for n in names}
    subset = [n for n in names if int(n[11:14]) <= 3]
    rng = np.random.default_rng(RNG_SEED)
    # Per-photo training samples for each method, computed once.
    samples = {m: {} for m in [*METHODS, "ilastik"]}
    ila_feats = {}
    for i, n in enumerate(names):
        photo, mask = load("dubai", n)
        for m, opts in METHODS.items():
            samples[m][n] = _pair_samples(photo, mask, i, classes, opts)
        if n in subset:
            feats, secs = ilastik_features(photo)
            sel = labelled_pixels(mask, classes, 20000, rng)
            samples["ilastik"][n] = (feats.reshape(-1, feats.shape[2])[sel], mask.ravel()[sel])
            pick = labelled_pixels(mask, classes, ILASTIK_TEST_PIXELS, rng)
            ila_feats[n] = (feats.reshape(-1, feats.shape[2])[pick], mask.ravel()[pick], secs,
                            mask.size)
            del feats
        log(f"  features {i + 1}/{len(names)}")
    per_photo = {m: {} for m in [*METHODS, ADAPT, "ilastik", "kmeans-colour",
                                 "kmeans-oracle"]}
    speed = {m: [0.0, 0.0] for m in per_photo}  # [pixels, seconds]
    for tile in range(1, 7):
        train = [n for n in names if tile_of[n] != tile]
        test = [n for n in names if tile_of[n] == tile]
        for m in [*METHODS, "ilastik"]:
            pool = [n for n in train if n in samples[m]]
            x, y = _capped(samples[m], pool, ACROSS_CAP, rng)
            if m == "ilastik":
                models = {m: ilastik_model(x, y)}
            else:
                # adapt=None as train_classifier decides it (off for 45 photos); ADAPT is
                # the same forest adapting to each photo.
                opts = METHODS[m]
                models = {m: Classifier(build_forest(x, y, opts), tuple(np.unique(y)),
                                        opts.resolved(len(pool), scribbles=False))}
            if m == "rf-default":
                models[ADAPT] = Classifier(models[m].forest, models[m].classes,
                                           replace(opts, adapt=True))
            model = models[m]
            for n in test:
                if m == "ilastik":
                    if n not in ila_feats:
                        continue
                    fx, fy, secs, npx = ila_feats[n]
                    pred, dt = timed_votes(model, fx)
                    per_photo[m][n] = confusion(fy, pred, classes)
                    speed[m][0] += npx
                    speed[m][1] += secs + dt * npx / len(fx)
                    continue
                photo, mask = load("dubai", n)
                for mm, model in models.items():
                    t = time.perf_counter()
                    res = model.predict(photo)
                    speed[mm][1] += time.perf_counter() - t
                    speed[mm][0] += mask.size
                    per_photo[mm][n] = confusion(mask, res.labels, classes)
        # k-means on the training tiles' coarse Lab, clusters -> majority class there.
        x, y = _capped(samples["rf-colour"], train, ACROSS_CAP, rng)
        kmeans_trained = ColourKMeans(x, y, KMEANS_CLUSTERS)
        for n in test:
            photo, mask = load("dubai", n)
            cm, mpxs = kmeans_predict(photo, mask, classes, mask)
            per_photo["kmeans-oracle"][n] = cm
            speed["kmeans-oracle"][0] += mask.size
            speed["kmeans-oracle"][1] += mask.size / mpxs / 1e6
            cm, secs = kmeans_trained.classify(photo, mask, classes)
            per_photo["kmeans-colour"][n] = cm
            speed["kmeans-colour"][0] += mask.size
            speed["kmeans-colour"][1] += secs
        log(f"  fold tile {tile} done")
    out = {}
    for m, cms in per_photo.items():
        out[m] = scores(sum(cms.values()), classes)
        out[m]["photos"] = len(cms)
        out[m]["mpx_per_s"] = speed[m][0] / max(speed[m][1], 1e-9) / 1e6
        sub = [cms[n] for n in subset if n in cms]
        out[m]["subset_001_003"] = scores(sum(sub), classes)
    return out


def _capped(per_photo_samples, names, cap, rng):
    xs, ys = [], []
    for n in names:
        x, y = per_photo_samples[n]
        xs.append(x)
        ys.append(y)
    x, y = np.concatenate(xs), np.concatenate(ys).astype(np.int32)
    keep = []
    for k in np.unique(y):
        idx = np.flatnonzero(y == k)
        keep.append(rng.choice(idx, min(cap, len(idx)), replace=False))
    keep = np.concatenate(keep)
    return x[keep].astype(np.float32), y[keep]


def scribble_sets():
    """The 16 photos of the scribble parts: (folder, name, classes, crop)."""
    sets = [("dubai", n, [1, 2, 3, 4, 5], None)
            for n in sorted(p.name for p in (DATA / "dubai" / "images").glob("*.jpg"))
            if n[11:14] in ("004", "005")]
    sets += [("loveda", "loveda_0.png", [1, 2, 3, 4, 5, 6, 7], None),
             ("loveda", "loveda_1.png", [1, 2, 3, 4, 5, 6, 7], None),
             ("potsdam", "potsdam_2_10_0_0_512_512.png", [1, 2, 3, 4, 5, 6], None),
             ("deepglobe", "6399_sat.jpg", [1, 2, 3, 4, 5, 6], 1536)]
    return sets


def _train_one(photo, scr, opts):
    from terratheme.core.classify import train_classifier

    return train_classifier([(photo, scr)], opts)


def memory(log):
    """tracemalloc peak of rf-default predict on photos tiled from a Dubai sample."""
    photo, mask = load("dubai", "image_part_004t4.jpg")
    scr = simulate_scribbles(mask, [1, 2, 3, 4, 5], np.random.default_rng(5))
    model = _train_one(photo, scr, SupervisedOptions())
    out = {}
    for size in (2048, 4096, 8192):
        reps = (-(-size // photo.shape[0]), -(-size // photo.shape[1]), 1)
        big = np.ascontiguousarray(np.tile(photo, reps)[:size, :size])
        tracemalloc.start()
        t = time.perf_counter()
        res = model.predict(big)
        dt = time.perf_counter() - t
        _cur, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        outputs = res.labels.nbytes + res.confidence.nbytes
        out[str(size)] = {"peak_mb": peak / 2**20, "outputs_mb": outputs / 2**20,
                          "working_mb": (peak - outputs) / 2**20,
                          "mpx_per_s": size * size / dt / 1e6}
        log(f"  memory {size}: working {(peak - outputs) / 2**20:.0f} MB, "
            f"{size * size / dt / 1e6:.1f} Mpx/s")
        del big, res
    return out


def main() -> int:
    if not DATA.is_dir():
        print(f"{DATA} is absent: nothing to benchmark")
        return 0
    t0 = time.perf_counter()

    def log(msg):
        print(f"[{time.perf_counter() - t0:6.0f} s] {msg}", flush=True)

    result = {"cv2_threads": cv2.getNumThreads()}
    OUT.mkdir(parents=True, exist_ok=True)
    every = ("scribbles", "corrections", "across_tiles", "one_per_tile", "train_cost", "aerial",
             "memory")
    parts = sys.argv[1:] or list(every)
    if "--scribbles-only" in parts:
        parts = ["scribbles", "corrections"]
    if unknown := set(parts) - set(every):
        print(f"unknown part(s) {sorted(unknown)}: choose from {every} or --scribbles-only")
        return 2
    previous = OUT / "classify.json"
    if len(set(parts)) < len(every) and previous.is_file():
        result.update(json.loads(previous.read_text()))
    keys = {"corrections": "scribbles_corrections"}
    for part, fn in (("scribbles", scribbles), ("corrections", corrections),
                     ("across_tiles", across_tiles), ("one_per_tile", one_per_tile),
                     ("train_cost", train_cost), ("aerial", aerial), ("memory", memory)):
        if part in parts:
            log(part)
            started = time.perf_counter()
            out = fn(log)
            result.setdefault("part_seconds", {})[part] = time.perf_counter() - started
            if part == "scribbles":
                out, result["scribbles_budget"] = out
            result[keys.get(part, part)] = out
            (OUT / "classify.partial.json").write_text(json.dumps(result, indent=1))
    base = result["across_tiles"]["ilastik"]
    result["ratios_vs_ilastik"] = {
        m: {"speed": r["mpx_per_s"] / base["mpx_per_s"],
            "miou_subset_gain": r["subset_001_003"]["miou"] - base["subset_001_003"]["miou"]}
        for m, r in result["across_tiles"].items()
    }
    result["seconds"] = time.perf_counter() - t0
    (OUT / "classify.partial.json").unlink(missing_ok=True)
    (OUT / "classify.json").write_text(json.dumps(result, indent=1))
    chart(result, OUT / "classify.png")
    for part in ("across_tiles", "scribbles"):
        for m, r in result[part].items():
            if m in ("coverage", "draws", "budget"):
                continue
            miou = r.get("miou", r.get("mean_miou_over_photos"))
            log(f"{part:12s} {m:14s} mIoU {miou:.3f}  {r['mpx_per_s']:.2f} Mpx/s")
    for m, r in result.get("one_per_tile", {}).items():
        if isinstance(r, dict):
            log(f"one_per_tile {m:14s} mean tile mIoU {r['mean_tile_miou']:.3f} "
                f"(+/- {r['std_tile_miou']:.3f} over tiles), per photo {r['mean_photo_miou']:.3f}"
                f"  {r['mpx_per_s']:.2f} Mpx/s")
    for m, rows in result.get("scribbles_corrections", {}).items():
        for v, r in rows.items() if m not in ("coverage", "repeats", "low_confidence_share") \
                else ():
            log(f"corrections  {m:14s} {v:14s} mIoU {r['mean_miou_over_photos']:.3f}  "
                f"Dubai pooled {r['dubai_pooled']['miou']:.3f}  "
                f"Dubai per-photo {r['dubai_mean_miou_over_photos']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
