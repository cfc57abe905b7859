"""The fitted-model cache: the same model, from memory or disk, by everything the fit uses."""

from __future__ import annotations

import io
import json
import os
import re
import zipfile
from dataclasses import replace

import numpy as np
import pytest
from classify_cases import block_pairs as pairs
from terratheme.core.classify import (
    ModelCache,
    SampleCache,
    SupervisedOptions,
    train_classifier,
)
from terratheme.core.classify import model_cache as model_cache_module
from terratheme.core.classify.keyed_store import KeyedStore
from terratheme.core.classify.model_cache import model_key
from terratheme.core.classify.model_file import model_bytes
from terratheme.core.errors import TerrathemeError

#: few trees: the tests fit often
OPTS = SupervisedOptions(n_trees=8)
FOREST = ("classes", "roots", "feature", "threshold", "left", "right", "value")



def assert_same_model(a, b, target):
    for name in FOREST:
        np.testing.assert_array_equal(getattr(a.forest, name), getattr(b.forest, name))
    assert (a.classes, a.options, a.class_weights) == (b.classes, b.options, b.class_weights)
    pa, pb = a.predict(target), b.predict(target)
    np.testing.assert_array_equal(pa.labels, pb.labels)
    np.testing.assert_array_equal(pa.confidence, pb.confidence)


@pytest.fixture(scope="module")
def trained():
    """Six training pairs, their samples (cached) and the model fitted on them uncached."""
    data = pairs(6)
    samples = SampleCache()
    return data, samples, train_classifier(data, OPTS, cache=samples)


def test_a_cached_model_predicts_bit_identically(tmp_path, trained):
    data, samples, fitted = trained
    target = pairs(1, seed=9)[0][0]
    models = ModelCache(tmp_path)
    first = train_classifier(data, OPTS, cache=samples, model_cache=models)   # fitted, kept
    again = train_classifier(data, OPTS, cache=samples, model_cache=models)   # from memory
    assert (models.hits, models.misses) == (1, 1)
    assert len(list(tmp_path.glob("*.model.npz"))) == 1
    # From disk, with an empty sample cache: no pair's samples are even looked up.
    fresh_samples, fresh_models = SampleCache(), ModelCache(tmp_path)
    from_disk = train_classifier(data, OPTS, cache=fresh_samples, model_cache=fresh_models)
    assert (fresh_models.hits, fresh_models.misses) == (1, 0)
    assert fresh_samples.hits + fresh_samples.misses == 0
    for model in (first, again, from_disk):
        assert_same_model(model, fitted, target)


def test_a_memory_hit_is_a_model_of_its_own(trained):
    data, samples, _ = trained
    models = ModelCache()
    a = train_classifier(data, OPTS, cache=samples, model_cache=models)
    a.name_classes({1: "grass"})
    b = train_classifier(data, OPTS, cache=samples, model_cache=models)
    assert models.hits == 1 and b.class_names is None


def test_changing_any_ingredient_changes_the_key(monkeypatch):
    keys, classes, opts = ["a" * 64, "b" * 64], [1, 2, 3], OPTS.resolved(2, False)
    base = model_key(keys, classes, opts)
    assert base == model_key(list(keys), (1, 2, 3), replace(opts))
    variants = [
        model_key(keys[::-1], classes, opts),
        model_key(keys[:1], classes, opts),
        model_key([keys[0], "c" * 64], classes, opts),
        model_key(keys, [1, 2], opts),
        model_key(keys, classes, replace(opts, seed=1)),
        model_key(keys, classes, replace(opts, n_trees=9)),
        model_key(keys, classes, replace(opts, max_depth=11)),
        model_key(keys, classes, replace(opts, min_samples=5)),
        model_key(keys, classes, replace(opts, balance=False)),
        model_key(keys, classes, replace(opts, samples_per_pair=401)),
        model_key(keys, classes, replace(opts, prior_power=0.5)),
        model_key(keys, classes, replace(opts, adapt=not opts.adapt)),
        model_key(keys, classes, replace(opts, features=replace(
            opts.features, scale=opts.features.scale * 2))),
        model_key(keys, classes, opts, {1: 1.0, 2: 2.0, 3: 1.0}),
        model_key(keys, classes, opts, {1: 1.0, 2: 2.5, 3: 1.0}),
    ]
    monkeypatch.setattr(model_cache_module, "CACHE_VERSION", model_cache_module.CACHE_VERSION + 1)
    variants.append(model_key(keys, classes, opts))
    monkeypatch.undo()
    monkeypatch.setattr(model_cache_module, "version", lambda name: "0.0")
    variants.append(model_key(keys, classes, opts))
    assert len({base, *variants}) == len(variants) + 1


def test_another_pair_or_seed_is_a_miss(tmp_path, trained):
    data, samples, _ = trained
    models = ModelCache(tmp_path)
    train_classifier(data, OPTS, cache=samples, model_cache=models)
    edited = [(p.copy(), m.copy()) for p, m in data]
    edited[3][1][0, 0] = 3 if edited[3][1][0, 0] != 3 else 1
    train_classifier(edited, OPTS, cache=samples, model_cache=models)
    train_classifier(data, replace(OPTS, seed=5), cache=samples, model_cache=models)
    train_classifier(data[:5], OPTS, cache=samples, model_cache=models)
    assert (models.hits, models.misses) == (0, 4)
    assert len(list(tmp_path.glob("*.model.npz"))) == 4


def _entry(key, model, **extra):
    buf = io.BytesIO()
    np.savez(buf, key=np.frombuffer(key.encode(), np.uint8),
             model=np.frombuffer(model, np.uint8), **extra)
    return buf.getvalue()


def _typed(key, model):
    buf = io.BytesIO()
    np.savez(buf, key=np.frombuffer(key.encode(), np.uint8),
             model=np.frombuffer(model + b"\0" * (len(model) % 2), np.uint16))
    return buf.getvalue()


def _newer_version(model: bytes) -> bytes:
    src, out = zipfile.ZipFile(io.BytesIO(model)), io.BytesIO()
    with zipfile.ZipFile(out, "w") as dst:
        for name in src.namelist():
            data = src.read(name)
            if name == "meta.json":
                meta = json.loads(data)
                meta["version"] = 99
                data = json.dumps(meta).encode()
            dst.writestr(name, data)
    return out.getvalue()


@pytest.mark.parametrize("damage", ["truncate", "garbage", "other_key", "other_options",
                                    "newer_version", "not_bytes", "damaged_model"])
def test_a_damaged_entry_is_fitted_again_and_replaced(tmp_path, trained, damage):
    data, samples, fitted = trained
    train_classifier(data, OPTS, cache=samples, model_cache=ModelCache(tmp_path))
    (path,) = tmp_path.glob("*.model.npz")
    key = path.name[: -len(".model.npz")]
    good = model_bytes(fitted.parts())
    other = model_bytes(fitted.parts()._replace(options=replace(fitted.options, seed=3)))
    path.write_bytes({
        "truncate": lambda: path.read_bytes()[:300],
        "garbage": lambda: b"\x00" * 64,
        "other_key": lambda: _entry("0" * 64, good),
        "other_options": lambda: _entry(key, other),
        "newer_version": lambda: _entry(key, _newer_version(good)),
        "not_bytes": lambda: _typed(key, good),      # the model's very bytes, as uint16
        "damaged_model": lambda: _entry(key, good[: len(good) // 2]),
    }[damage]())
    models = ModelCache(tmp_path)
    model = train_classifier(data, OPTS, cache=samples, model_cache=models)
    assert (models.hits, models.misses) == (0, 1)
    assert_same_model(model, fitted, pairs(1, seed=9)[0][0])
    again = ModelCache(tmp_path)
    train_classifier(data, OPTS, cache=samples, model_cache=again)
    assert (again.hits, again.misses) == (1, 0)


def test_a_model_no_file_can_hold_is_kept_in_memory_only(tmp_path):
    models = ModelCache(tmp_path)
    opts = replace(OPTS, max_depth=65)            # deeper than a model file allows
    with pytest.raises(TerrathemeError, match="max_depth must be a whole number in 1..64"):
        model_bytes(train_classifier(pairs(2), opts).parts())
    a = train_classifier(pairs(2), opts, model_cache=models)
    b = train_classifier(pairs(2), opts, model_cache=models)
    assert (models.hits, models.misses) == (1, 1) and b.forest is a.forest
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("folder", ["unwritable", "under_a_file"])
@pytest.mark.parametrize(("cache", "what"), [("cache", "training samples"),
                                             ("model_cache", "trained models")])
def test_a_folder_that_cannot_be_written_is_one_clear_error(tmp_path, folder, cache, what):
    if folder == "unwritable":
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            pytest.skip("root writes into read-only folders")
        path = tmp_path / "ro"
        path.mkdir()
        path.chmod(0o500)
    else:
        (tmp_path / "file").write_bytes(b"x")
        path = tmp_path / "file" / "cache"
    made = SampleCache(path) if cache == "cache" else ModelCache(path)
    try:
        with pytest.raises(TerrathemeError, match=f"{re.escape(str(path))}: cannot keep {what} "
                                                  f"there"):
            train_classifier(pairs(1), OPTS, **{cache: made})
    finally:
        if folder == "unwritable":
            path.chmod(0o700)


def test_the_memory_keeps_the_most_recent_entries():
    store = KeyedStore(None, ".npz", 2, "things")
    store.remember("a", 1)
    store.remember("b", 2)
    assert store.recall("a") == 1          # now the most recent
    store.remember("c", 3)
    assert (store.recall("a"), store.recall("b"), store.recall("c")) == (1, None, 3)
    assert store.path("a") is None and store.read_arrays("a", ("x",)) is None
