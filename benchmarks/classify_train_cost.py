"""Part "train_cost" of ``bench_classify.py``: train on six photos, classify a seventh.

A user converts many photos with one set of labelled photos. Measured, all in
the same run, the median of ``REPEATS``:

  predict   classifying the target alone (a model already trained);
  cold      reading the six training pairs (issue 17's set, full masks,
            ``--ignore 6 7``) and the target from disk, training, classifying;
  warm      the same with the training samples in a
            :class:`core.classify.sample_cache.SampleCache` folder filled by an
            earlier run (a fresh cache object, so entries come from disk);
  previous  ``cold`` with the options of before issue 17 (15000 samples per class,
            no adaptation): the peer;
  cli       ``python -m app.cli classify TARGET -o L.png --train P M (x6) --ignore 6 7``
            end to end in a subprocess (interpreter start and imports included),
            once.

The target is a 1224 x 1224 crop (1.5 Mpx) of DeepGlobe 6399. Goals (issue 17):
``cold`` under 10 s on 2 cores, ``warm`` no more than twice ``predict``.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from classify_one_per_tile import IGNORE, ISSUE_SET

from core.classify import FeatureOptions, SupervisedOptions, train_classifier
from core.classify.sample_cache import SampleCache
from core.io.images import read_image, write_image

REPEATS = 3
TARGET_SIDE = 1224


def _pairs(bench):
    folder = bench.DATA / "dubai"
    return [(read_image(folder / "images" / n)[:, :, :3],
             read_image(folder / "masks" / (Path(n).stem + ".png"))[:, :, 0])
            for n in ISSUE_SET]


def _run(bench, target_path, options, cache_dir=None):
    """Read, train, classify -> (seconds, training seconds)."""
    t = time.perf_counter()
    pairs = _pairs(bench)
    target = read_image(target_path)
    cache = None if cache_dir is None else SampleCache(cache_dir)
    model = train_classifier(pairs, options, cache=cache)
    trained = time.perf_counter() - t
    model.predict(target)
    return time.perf_counter() - t, trained, model, target


def train_cost(log):
    """The timings above -> row."""
    import bench_classify as bench

    options = SupervisedOptions(ignore_classes=IGNORE)
    previous = replace(options, adapt=False, max_samples_per_class=15000, samples_per_pair=15000,
                       features=FeatureOptions(hessian=True, ridge_sigmas=(1.0, 2.0, 4.0)))
    out: dict = {"target_px": TARGET_SIDE * TARGET_SIDE, "repeats": REPEATS}
    with tempfile.TemporaryDirectory() as tmp:
        target_path = Path(tmp) / "target.png"
        photo, _mask = bench.load("deepglobe", "6399_sat.jpg", TARGET_SIDE)
        write_image(target_path, photo)
        cache_dir = Path(tmp) / "samples"
        times = {k: [] for k in ("predict", "cold", "cold_train", "warm", "warm_train",
                                 "previous", "previous_train")}
        for _ in range(REPEATS):
            secs, train, model, target = _run(bench, target_path, options)
            times["cold"].append(secs)
            times["cold_train"].append(train)
            t = time.perf_counter()
            model.predict(target)
            times["predict"].append(time.perf_counter() - t)
            _run(bench, target_path, options, cache_dir)    # fills the cache (if empty)
            secs, train, _m, _t = _run(bench, target_path, options, cache_dir)
            times["warm"].append(secs)
            times["warm_train"].append(train)
            secs, train, _m, _t = _run(bench, target_path, previous)
            times["previous"].append(secs)
            times["previous_train"].append(train)
        med = {k: float(np.median(v)) for k, v in times.items()}
        out.update({f"{k}_s": v for k, v in med.items()})
        out["warm_over_predict"] = med["warm"] / med["predict"]
        out["predict_mpx_per_s"] = TARGET_SIDE * TARGET_SIDE / med["predict"] / 1e6
        # The CLI end to end, once.
        cmd = [sys.executable, "-m", "app.cli", "classify", str(target_path), "-o",
               str(Path(tmp) / "labels.png"), "--ignore", *map(str, IGNORE)]
        for n in ISSUE_SET:
            cmd += ["--train", str(bench.DATA / "dubai" / "images" / n),
                    str(bench.DATA / "dubai" / "masks" / (Path(n).stem + ".png"))]
        t = time.perf_counter()
        subprocess.run(cmd, check=True, cwd=bench.REPO, capture_output=True)
        out["cli_s"] = time.perf_counter() - t
        out["cli_mpx_per_s"] = TARGET_SIDE * TARGET_SIDE / out["cli_s"] / 1e6
    log(f"  train_cost: predict {med['predict']:.2f} s, cold {med['cold']:.2f} s "
        f"(train {med['cold_train']:.2f}), warm {med['warm']:.2f} s "
        f"(train {med['warm_train']:.2f}; {out['warm_over_predict']:.2f}x predict), "
        f"previous {med['previous']:.2f} s, CLI {out['cli_s']:.2f} s")
    return out
