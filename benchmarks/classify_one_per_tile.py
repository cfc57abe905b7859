"""Part "one_per_tile" of ``bench_classify.py``: train on one photo per tile, classify another area.

Issue 17's protocol. A user labels a handful of photos, one per area, and
converts photos of an area none of them shows. For each Dubai tile T (the
held-out tile) the classifier is trained with full label masks on one photo
of each of the five other tiles (classes 1-5; 6 and 7 ignored, as
``--ignore 6 7``) and scored on every photo of tile T; a row gives the mIoU of
each held-out tile (its 9 photos pooled), their mean and spread, and the mean
mIoU per photo.

Training photos, ``DRAWS`` draws: draw 0 is the issue's set (``image_part_001t1,
002t2, 001t3, 005t4, 002t5, 003t6``, the photo of tile T left out); draws 1..
take one part per tile at random (``numpy.random.default_rng(DRAW_SEED + d)``),
the same for every held-out tile. Which photos train moves a row by several
hundredths, more than most methods differ, so every method is scored on the same
draws and rows give the mean over them (per-draw figures kept).

Methods, each the robustness piece of issue 17 on its own, then together:

  plain            the library default without the adaptation (training samples
                   capped per class by ``SupervisedOptions.samples_per_class``: 2000
                   for five photos);
  +adapt           plain + test-time adaptation (core/classify/adapt.py);
  rf-default       the library default now;
  rf-nostructure   rf-default without the structure features (core/classify/texture.py);
  rf-previous      the library default of before issue 17 (15000 samples per class,
                   no adaptation);
  ilastik          draw 0 only, the ilastik recipe (classify_peers.py), trained on
                   20,000 random labelled pixels per training photo and scored on 50,000
                   random pixels of parts 001-003 of the held-out tile; rf-default's
                   row carries the same subset (``subset_001_003``).

Mpx/s: prediction only (the photo's whole classification, adaptation included).
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import replace

import numpy as np
from classify_eval import confusion, scores
from classify_peers import labelled_pixels, timed_votes
from terratheme.core.classify import FeatureOptions, SupervisedOptions, train_classifier
from terratheme.core.io.disk_cache import DiskCache

CLASSES = [1, 2, 3, 4, 5]
IGNORE = (6, 7)
#: the issue's six training photos, one per tile
ISSUE_SET = ("image_part_001t1.jpg", "image_part_002t2.jpg", "image_part_001t3.jpg",
             "image_part_005t4.jpg", "image_part_002t5.jpg", "image_part_003t6.jpg")
#: draws of training photos (draw 0 = ISSUE_SET)
DRAWS = 3
DRAW_SEED = 17
#: training pixels per photo and test pixels per photo of the ilastik recipe
ILASTIK_TRAIN_PIXELS = 20_000


def _plain() -> SupervisedOptions:
    return SupervisedOptions(ignore_classes=IGNORE, adapt=False)


def methods() -> dict[str, SupervisedOptions]:
    """The rows' options (see the module docstring)."""
    plain = _plain()
    fo = plain.features
    default = SupervisedOptions(ignore_classes=IGNORE)
    return {
        "plain": plain,
        "+adapt": replace(plain, adapt=True),
        "rf-default": default,
        "rf-nostructure": replace(default, features=replace(fo, structure=False)),
        "rf-previous": replace(plain, max_samples_per_class=15000, samples_per_pair=15000,
                               features=FeatureOptions(hessian=True, ridge_sigmas=(1.0, 2.0, 4.0))),
    }


def tile_of(name: str) -> int:
    return int(name.split("t")[-1].split(".")[0])


def random_draw(names, seed) -> tuple[str, ...]:
    """One photo of each tile at random (``numpy.random.default_rng(seed)``)."""
    rng = np.random.default_rng(seed)
    return tuple(rng.choice(sorted(n for n in names if tile_of(n) == t)) for t in range(1, 7))


def training_draws(names) -> list[tuple[str, ...]]:
    """One photo per tile for each draw (draw 0: the issue's set)."""
    return [ISSUE_SET] + [random_draw(names, DRAW_SEED + d) for d in range(1, DRAWS)]


def score_draw(photos, train, opts, cache=None) -> tuple[dict[str, np.ndarray], int, float]:
    """Every held-out tile of one draw -> ({photo: confusion}, pixels, predict seconds).

    ``photos``: ``{name: (photo, mask)}`` of every Dubai photo; ``train``: one
    photo name per tile (the held-out tile's is left out of its training).
    """
    cms, pixels, seconds = {}, 0, 0.0
    for tile in range(1, 7):
        model = train_classifier([photos[n] for n in train if tile_of(n) != tile], opts,
                                 cache=cache)
        for n in sorted(photos):
            if tile_of(n) != tile:
                continue
            photo, mask = photos[n]
            t = time.perf_counter()
            res = model.predict(photo)
            seconds += time.perf_counter() - t
            pixels += mask.size
            cms[n] = confusion(mask, res.labels, CLASSES)
    return cms, pixels, seconds


def _tile_mious(cms: dict[str, np.ndarray]) -> list[float]:
    """mIoU of each held-out tile, its photos' confusions pooled."""
    return [scores(sum(cms[n] for n in cms if tile_of(n) == t), CLASSES)["miou"]
            for t in sorted({tile_of(n) for n in cms})]


def rows_of(per_draw: list[dict[str, np.ndarray]], subset) -> dict:
    """Result row from per-draw ``{photo: confusion}``.

    ``subset_001_003`` is the mean tile mIoU over parts 001-003 only (the
    ilastik recipe's photos).
    """
    out_draws = []
    for cms in per_draw:
        per_tile = _tile_mious(cms)
        per_photo = [scores(cm, CLASSES)["miou"] for cm in cms.values()]
        sub = _tile_mious({n: cm for n, cm in cms.items() if n in subset})
        out_draws.append({"mean_tile_miou": float(np.mean(per_tile)),
                          "std_tile_miou": float(np.std(per_tile)),
                          "tile_miou": [round(v, 4) for v in per_tile],
                          "mean_photo_miou": float(np.mean(per_photo)),
                          "pooled": scores(sum(cms.values()), CLASSES),
                          "subset_001_003": float(np.mean(sub))})
    mean = {k: float(np.mean([d[k] for d in out_draws]))
            for k in ("mean_tile_miou", "std_tile_miou", "mean_photo_miou")}
    mean["mean_tile_miou_per_draw"] = [round(d["mean_tile_miou"], 4) for d in out_draws]
    return {**mean, "draws": out_draws}


def one_per_tile(log):
    """Every method on every draw and held-out tile -> rows."""
    import bench_classify as bench

    names = sorted(p.name for p in (bench.DATA / "dubai" / "images").glob("*.jpg"))
    photos = {n: bench.load("dubai", n) for n in names}
    subset = {n for n in names if int(n[11:14]) <= 3}
    draws = training_draws(names)
    folder = tempfile.TemporaryDirectory()      # removed when the run ends
    cache = DiskCache(folder.name)
    rows, speed = {}, {}
    done: dict[SupervisedOptions, str] = {}
    for m, opts in methods().items():
        # adapt=None as train_classifier decides it for five photos' masks.
        key = opts.resolved(5, scribbles=False)
        if key in done:
            # The same options as an earlier row (e.g. the default is one piece on).
            rows[m] = {**rows[done[key]], "same_as": done[key]}
            continue
        done[key] = m
        per_draw = []
        pixels, seconds = 0, 0.0
        for d, train in enumerate(draws):
            cms, px, secs = score_draw(photos, train, opts, cache)
            pixels += px
            seconds += secs
            per_draw.append(cms)
            log(f"  one_per_tile {m} draw {d}: mean tile mIoU "
                f"{rows_of([cms], subset)['mean_tile_miou']:.3f}")
        rows[m] = rows_of(per_draw, subset)
        speed[m] = pixels / max(seconds, 1e-9) / 1e6
        rows[m]["mpx_per_s"] = speed[m]
    rows["ilastik"] = _ilastik(bench, photos, draws[0], subset, log)
    return {"draws": [list(t) for t in draws], "classes": CLASSES, **rows}


def _ilastik(bench, photos, train_set, subset, log):
    """The ilastik recipe on draw 0, scored on random pixels of the subset's photos."""
    rng = np.random.default_rng(bench.RNG_SEED)
    feats, samples = {}, {}
    pixels, seconds = 0, 0.0
    for n in sorted(set(train_set) | subset):
        photo, mask = photos[n]
        f, secs = bench.ilastik_features(photo)
        flat, truth = f.reshape(-1, f.shape[2]), mask.ravel()
        if n in train_set:
            pick = labelled_pixels(truth, CLASSES, ILASTIK_TRAIN_PIXELS, rng)
            samples[n] = (flat[pick], truth[pick].astype(np.int32))
        if n in subset:
            pick = labelled_pixels(truth, CLASSES, bench.ILASTIK_TEST_PIXELS, rng)
            feats[n] = (flat[pick], truth[pick], secs, mask.size)
        del f, flat
    cms = {}
    for tile in range(1, 7):
        train = [n for n in train_set if tile_of(n) != tile]
        x = np.concatenate([samples[n][0] for n in train])
        y = np.concatenate([samples[n][1] for n in train])
        model = bench.ilastik_model(x, y)
        for n in sorted(feats):
            if tile_of(n) != tile:
                continue
            fx, fy, secs, npx = feats[n]
            pred, dt = timed_votes(model, fx)
            cms[n] = confusion(fy, pred, CLASSES)
            pixels += npx
            seconds += secs + dt * npx / len(fx)
    row = rows_of([cms], subset)
    row["mpx_per_s"] = pixels / max(seconds, 1e-9) / 1e6
    log(f"  one_per_tile ilastik (parts 001-003): mean tile mIoU {row['mean_tile_miou']:.3f}")
    return row
