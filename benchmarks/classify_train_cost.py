"""Part "train_cost" of ``bench_classify.py``: train on six photos, classify a seventh.

A user converts many photos with one set of labelled photos. Measured in
paired rounds (``REPEATS``, each path once per round, the order rotated), wall
and CPU seconds (``time.process_time``: the process's threads, so less
disturbed by the other sessions on the machine), medians and ranges:

  predict        classifying the target alone (a model already trained);
  cold           reading the six training pairs (issue 17's set, full masks,
                 ``--ignore 6 7``) and the target from disk, training, classifying;
  warm_samples   the same with the training samples in a
                 :class:`core.io.disk_cache.DiskCache` folder filled by an earlier run
                 (a fresh cache object, so entries come from disk) but no model there:
                 the forest is fitted again (its entry removed after each run);
  warm_model     the same with the fitted model in the folder too
                 (fresh objects: the model comes from disk); ``warm_model_read``
                 is its reading of the seven photos, ``warm_model_train`` its
                 training (the pairs' keys and the model's file);
  previous       ``cold`` with the options of before issue 17 (15000 samples per class,
                 no adaptation): the peer;
  cli            ``terratheme classify TARGET -o L.png --train P M (x6) --ignore 6 7``
                 end to end in a subprocess (interpreter start and imports included),
                 once without a cache, once with ``--cache-dir`` (filled by a run
                 before): ``cli_s`` / ``cli_cached_s`` wall, ``..._cpu_s`` the child's CPU.

The target is a 1224 x 1224 crop (1.5 Mpx) of DeepGlobe 6399. Goals (issue 17):
``cold`` under 10 s on 2 cores, ``warm`` no more than twice ``predict``
(``warm_model_over_predict``, CPU and wall, per round; the
``warm_samples_over_predict`` ratio is the path before the model cache).
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from classify_one_per_tile import IGNORE, ISSUE_SET
from terratheme.core.classify import FeatureOptions, SupervisedOptions, train_classifier
from terratheme.core.io.disk_cache import DiskCache
from terratheme.core.io.images import read_image, write_image

REPEATS = 5
TARGET_SIDE = 1224
PATHS = ("predict", "cold", "warm_samples", "warm_model", "previous")


def _pairs(bench):
    folder = bench.DATA / "dubai"
    return [(read_image(folder / "images" / n)[:, :, :3],
             read_image(folder / "masks" / (Path(n).stem + ".png"))[:, :, 0])
            for n in ISSUE_SET]


class _Clock:
    """Wall and CPU seconds since creation."""

    def __init__(self):
        self.wall, self.cpu = time.perf_counter(), time.process_time()

    def lap(self):
        return time.perf_counter() - self.wall, time.process_time() - self.cpu


def _run(bench, target_path, options, cache_dir=None):
    """Read, train, classify -> ({"all", "read", "train": (wall s, CPU s), "model_hits"},
    model, target)."""
    clock = _Clock()
    pairs = _pairs(bench)
    target = read_image(target_path)
    read = clock.lap()
    cache = None if cache_dir is None else DiskCache(cache_dir)
    model = train_classifier(pairs, options, cache=cache)
    trained = clock.lap()
    model.predict(target)
    times = {"all": clock.lap(), "read": read,
             "train": tuple(b - a for a, b in zip(read, trained, strict=True)),
             "model_hits": cache.hits["model"] if cache is not None else 0}
    return times, model, target


def _cli(bench, target_path, tmp, extra=()):
    """The CLI end to end in a subprocess -> (wall s, the child's CPU s)."""
    cmd = [sys.executable, "-m", "terratheme.app.cli", "classify", str(target_path), "-o",
           str(Path(tmp) / "labels.png"), "--ignore", *map(str, IGNORE), *extra]
    for n in ISSUE_SET:
        cmd += ["--train", str(bench.DATA / "dubai" / "images" / n),
                str(bench.DATA / "dubai" / "masks" / (Path(n).stem + ".png"))]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=bench.REPO, capture_output=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def _summary(values):
    return {"median": float(np.median(values)), "min": float(np.min(values)),
            "max": float(np.max(values))}


def train_cost(log):
    """The timings above -> row."""
    import bench_classify as bench

    options = SupervisedOptions(ignore_classes=IGNORE)
    previous = replace(options, adapt=False, max_samples_per_class=15000, samples_per_pair=15000,
                       features=FeatureOptions(hessian=True, ridge_sigmas=(1.0, 2.0, 4.0)))
    out: dict = {"target_px": TARGET_SIDE * TARGET_SIDE, "repeats": REPEATS,
                 "load_before": os.getloadavg()}
    with tempfile.TemporaryDirectory() as tmp:
        target_path = Path(tmp) / "target.png"
        photo, _mask = bench.load("deepglobe", "6399_sat.jpg", TARGET_SIDE)
        write_image(target_path, photo)
        cache_dir, samples_dir = Path(tmp) / "cache", Path(tmp) / "samples"
        # Fills the cache with samples and model (and loads every kernel).
        _times, model, target = _run(bench, target_path, options, cache_dir)
        shutil.copytree(cache_dir, samples_dir, ignore=shutil.ignore_patterns("*.model"))
        folders = {"warm_samples": samples_dir, "warm_model": cache_dir}
        rounds: list[dict] = []
        for r in range(REPEATS):
            row = {}
            for path in PATHS[r % len(PATHS):] + PATHS[:r % len(PATHS)]:
                if path == "predict":
                    clock = _Clock()
                    model.predict(target)
                    row["predict"] = clock.lap()
                    continue
                opts = previous if path == "previous" else options
                times, _m, _t = _run(bench, target_path, opts, folders.get(path))
                for entry in samples_dir.glob("*.model"):
                    entry.unlink()
                if path == "warm_model" and times["model_hits"] != 1:
                    raise RuntimeError("the warm path did not take the model from the cache")
                row[path] = times["all"]
                row[f"{path}_train"] = times["train"]
                row[f"{path}_read"] = times["read"]
            rounds.append(row)
        for name in rounds[0]:
            for kind, col in (("s", 0), ("cpu_s", 1)):
                out[f"{name}_{kind}"] = _summary([row[name][col] for row in rounds])
        for warm in ("warm_samples", "warm_model"):
            for kind, col in (("", 0), ("_cpu", 1)):
                out[f"{warm}_over_predict{kind}"] = _summary(
                    [row[warm][col] / row["predict"][col] for row in rounds])
        out["predict_mpx_per_s"] = TARGET_SIDE * TARGET_SIDE / out["predict_s"]["median"] / 1e6
        # The CLI end to end, once without a cache, once with a filled one.
        out["cli_s"], out["cli_cpu_s"] = _cli(bench, target_path, tmp)
        out["cli_mpx_per_s"] = TARGET_SIDE * TARGET_SIDE / out["cli_s"] / 1e6
        cli_cache = ["--cache-dir", str(Path(tmp) / "cli_cache")]
        _cli(bench, target_path, tmp, cli_cache)
        out["cli_cached_s"], out["cli_cached_cpu_s"] = _cli(bench, target_path, tmp, cli_cache)
    out["load_after"] = os.getloadavg()

    def med(name, kind="cpu_s"):
        return out[f"{name}_{kind}"]["median"]

    log(f"  train_cost (CPU s, medians of {REPEATS} paired rounds; load "
        f"{out['load_before'][0]:.1f} -> {out['load_after'][0]:.1f}): predict "
        f"{med('predict'):.2f}, cold {med('cold'):.2f} (train {med('cold_train'):.2f}), "
        f"warm_samples {med('warm_samples'):.2f} (train {med('warm_samples_train'):.2f}; "
        f"{out['warm_samples_over_predict_cpu']['median']:.2f}x predict), warm_model "
        f"{med('warm_model'):.2f} (read {med('warm_model_read'):.2f}, train "
        f"{med('warm_model_train'):.2f}; {out['warm_model_over_predict_cpu']['median']:.2f}x "
        f"predict, wall {out['warm_model_over_predict']['median']:.2f}x), previous "
        f"{med('previous'):.2f}; CLI {out['cli_s']:.2f} s wall ({out['cli_cpu_s']:.2f} CPU), "
        f"cached {out['cli_cached_s']:.2f} s ({out['cli_cached_cpu_s']:.2f} CPU)")
    return out
