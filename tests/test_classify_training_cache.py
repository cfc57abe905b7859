"""Training kept by content (core/classify/training_cache.py): the same samples and model from
the disk cache, every entry checked against its key (issue 33)."""

from __future__ import annotations

import io
import json
import os
import zipfile
from dataclasses import replace

import numpy as np
import pytest
from classify_cases import block_pairs as pairs
from terratheme.core.classify import SupervisedOptions, train_classifier
from terratheme.core.classify import training_cache as tc
from terratheme.core.classify.model_file import model_bytes
from terratheme.core.classify.supervised import collect_samples
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.disk_cache import DiskCache
from test_hostile_caches import forge

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
    """Six training pairs and the model fitted on them without a cache."""
    data = pairs(6)
    return data, train_classifier(data, OPTS)


@pytest.fixture(scope="module")
def target():
    return pairs(1, seed=9)[0][0]


# -- samples ------------------------------------------------------------------------

def test_cached_samples_are_identical_to_computed_ones(tmp_path):
    data, opts = pairs(), SupervisedOptions()
    x0, y0 = collect_samples(data, opts)
    cache = DiskCache(tmp_path)
    x1, y1 = collect_samples(data, opts, cache)
    assert (cache.hits["samples"], cache.misses["samples"]) == (0, 3)
    again = DiskCache(tmp_path)
    x2, y2 = collect_samples(data, opts, again)
    assert (again.hits["samples"], again.misses["samples"]) == (3, 0)
    np.testing.assert_array_equal(x2, x1)
    np.testing.assert_array_equal(y2, y1)
    # Features computed twice agree to float rounding only (OpenCV's vector paths).
    np.testing.assert_array_equal(y1, y0)
    np.testing.assert_allclose(x1, x0, rtol=1e-6, atol=1e-5)
    assert len(list(tmp_path.glob("*.samples"))) == 3


def test_the_sample_key_changes_with_anything_the_samples_depend_on():
    (photo, mask), = pairs(1)
    fo = SupervisedOptions().features
    base = tc.sample_key(photo, mask, (1, 2, 3), fo, 2048, 0.0)
    assert base == tc.sample_key(photo.copy(), mask.copy(), [1, 2, 3], fo, 2048, 0.0)
    other_photo = photo.copy()
    other_photo[0, 0, 0] ^= 1
    other_mask = mask.copy()
    other_mask[5, 5] = 0
    variants = [
        tc.sample_key(other_photo, mask, (1, 2, 3), fo, 2048, 0.0),
        tc.sample_key(photo, other_mask, (1, 2, 3), fo, 2048, 0.0),
        tc.sample_key(photo, mask, (1, 2), fo, 2048, 0.0),
        tc.sample_key(photo, mask, (1, 2, 3), replace(fo, hessian=not fo.hessian), 2048, 0.0),
        tc.sample_key(photo, mask, (1, 2, 3), fo, 1024, 0.0),
        tc.sample_key(photo, mask, (1, 2, 3), fo, 2048, 5.0),
        tc.sample_key(photo[:, :, :2].copy(), mask, (1, 2, 3), fo, 2048, 0.0),
    ]
    assert len({base, *variants}) == len(variants) + 1


def _forged_samples(key, x, y):
    return forge(key, "samples", {"features": x, "labels": y})


@pytest.mark.parametrize("damage", [
    "truncate", "garbage", "other_key", "wrong_width", "inf", "nan", "other_class",
    "forged_shape"])
def test_a_hostile_samples_entry_is_computed_again_and_replaced(tmp_path, target, damage):
    """+inf features were a scikit-learn traceback; a forged shape 'not enough memory' on
    every run (the entry never dropped)."""
    data, opts = pairs(1), SupervisedOptions(n_trees=8)
    fitted = train_classifier(data, opts, cache=DiskCache(tmp_path))
    next(tmp_path.glob("*.model")).unlink()          # the training must read the samples
    (path,) = tmp_path.glob("*.samples")
    key, good = path.name[:64], path.read_bytes()
    n = DiskCache(tmp_path).load(key, "samples", lambda a: len(a["labels"]))
    width = opts.features.n_features
    x, y = np.ones((n, width), np.float32), np.full(n, 1, np.uint8)
    header = {"key": key, "kind": "samples", "arrays": {
        "features": ["float32", [1 << 36, width]], "labels": ["uint8", [4]]}}
    path.write_bytes({
        "truncate": lambda: good[:100],
        "garbage": lambda: b"\x00" * 64,
        "other_key": lambda: _forged_samples("0" * 64, x, y),
        "wrong_width": lambda: _forged_samples(key, np.ones((n, width + 1), np.float32), y),
        "inf": lambda: _forged_samples(key, np.where(np.arange(x.size).reshape(x.shape) == 7,
                                                     np.float32(np.inf), x), y),
        "nan": lambda: _forged_samples(key, x * np.float32(np.nan), y),
        "other_class": lambda: _forged_samples(key, x, np.full_like(y, 9)),
        "forged_shape": lambda: forge("", "", {}, header=header, payload=bytes(64)),
    }[damage]())
    cache = DiskCache(tmp_path)
    model = train_classifier(data, opts, cache=cache)       # the samples are computed again
    assert (cache.hits["samples"], cache.misses["samples"]) == (0, 1)
    assert (model.predict(target).labels == fitted.predict(target).labels).mean() > 0.99
    again = DiskCache(tmp_path).load(key, "samples", lambda a: a)
    assert again is not None and np.isfinite(again["features"]).all()     # replaced


# -- models -------------------------------------------------------------------------

def test_a_cached_model_predicts_bit_identically(tmp_path, trained, target):
    data, fitted = trained
    cache = DiskCache(tmp_path)
    first = train_classifier(data, OPTS, cache=cache)
    assert (cache.hits["model"], cache.misses["model"]) == (0, 1)
    assert len(list(tmp_path.glob("*.model"))) == 1
    # From disk, with a fresh cache object: no pair's samples are even looked up.
    again = DiskCache(tmp_path)
    from_disk = train_classifier(data, OPTS, cache=again)
    assert (again.hits["model"], again.misses["model"]) == (1, 0)
    assert sum(again.hits.values()) + sum(again.misses.values()) == 1
    for model in (first, from_disk):
        assert_same_model(model, fitted, target)


def test_the_model_key_changes_with_any_ingredient(monkeypatch):
    keys, classes, opts = ["a" * 64, "b" * 64], [1, 2, 3], OPTS.resolved(2, False)
    base = tc.model_key(keys, classes, opts)
    assert base == tc.model_key(list(keys), (1, 2, 3), replace(opts))
    variants = [
        tc.model_key(keys[::-1], classes, opts),
        tc.model_key(keys[:1], classes, opts),
        tc.model_key([keys[0], "c" * 64], classes, opts),
        tc.model_key(keys, [1, 2], opts),
        tc.model_key(keys, classes, replace(opts, seed=1)),
        tc.model_key(keys, classes, replace(opts, n_trees=9)),
        tc.model_key(keys, classes, replace(opts, max_depth=11)),
        tc.model_key(keys, classes, replace(opts, min_samples=5)),
        tc.model_key(keys, classes, replace(opts, balance=False)),
        tc.model_key(keys, classes, replace(opts, samples_per_pair=401)),
        tc.model_key(keys, classes, replace(opts, prior_power=0.5)),
        tc.model_key(keys, classes, replace(opts, adapt=not opts.adapt)),
        tc.model_key(keys, classes, replace(opts, features=replace(
            opts.features, scale=opts.features.scale * 2))),
        tc.model_key(keys, classes, opts, {1: 1.0, 2: 2.0, 3: 1.0}),
        tc.model_key(keys, classes, opts, {1: 1.0, 2: 2.5, 3: 1.0}),
    ]
    monkeypatch.setattr(tc, "CACHE_VERSION", tc.CACHE_VERSION + 1)
    variants.append(tc.model_key(keys, classes, opts))
    monkeypatch.undo()
    monkeypatch.setattr(tc, "version", lambda name: "0.0")
    variants.append(tc.model_key(keys, classes, opts))
    assert len({base, *variants}) == len(variants) + 1


def test_another_pair_or_seed_is_a_miss(tmp_path, trained):
    data, _ = trained
    cache = DiskCache(tmp_path)
    train_classifier(data, OPTS, cache=cache)
    edited = [(p.copy(), m.copy()) for p, m in data]
    edited[3][1][0, 0] = 3 if edited[3][1][0, 0] != 3 else 1
    train_classifier(edited, OPTS, cache=cache)
    train_classifier(data, replace(OPTS, seed=5), cache=cache)
    train_classifier(data[:5], OPTS, cache=cache)
    assert (cache.hits["model"], cache.misses["model"]) == (0, 4)
    assert len(list(tmp_path.glob("*.model"))) == 4


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


def _model_entry(key, data: bytes, dtype=np.uint8):
    return forge(key, "model", {"model": np.frombuffer(data, dtype)})


@pytest.mark.parametrize("damage", [
    "truncate", "garbage", "renamed", "other_options", "newer_version", "not_bytes",
    "damaged_model", "swapped_model"])
def test_a_hostile_model_entry_is_fitted_again_and_replaced(tmp_path, trained, target, damage):
    """'swapped_model': another model's bytes under the key (the entry's digest kept) gave
    different labels silently; 'renamed': another key's whole entry."""
    data, fitted = trained
    train_classifier(data, OPTS, cache=DiskCache(tmp_path))
    (path,) = tmp_path.glob("*.model")
    key, entry = path.name[:64], path.read_bytes()
    good = model_bytes(fitted.parts())
    other = model_bytes(fitted.parts()._replace(options=replace(fitted.options, seed=3)))
    another = model_bytes(train_classifier(pairs(6, seed=4), OPTS).parts())
    path.write_bytes({
        "truncate": lambda: entry[:300],
        "garbage": lambda: b"\x00" * 64,
        "renamed": lambda: _model_entry("1" * 64, another),
        "other_options": lambda: _model_entry(key, other),
        "newer_version": lambda: _model_entry(key, _newer_version(good)),
        "not_bytes": lambda: _model_entry(key, good + b"\0" * (len(good) % 2), np.uint16),
        "damaged_model": lambda: _model_entry(key, good[: len(good) // 2]),
        "swapped_model": lambda: _model_entry(key, another)[:-32] + entry[-32:],
    }[damage]())
    cache = DiskCache(tmp_path)
    model = train_classifier(data, OPTS, cache=cache)
    assert (cache.hits["model"], cache.misses["model"]) == (0, 1)
    assert_same_model(model, fitted, target)
    again = DiskCache(tmp_path)
    train_classifier(data, OPTS, cache=again)
    assert (again.hits["model"], again.misses["model"]) == (1, 0)


def test_a_model_no_file_can_hold_is_not_kept(tmp_path):
    cache = DiskCache(tmp_path)
    opts = replace(OPTS, max_depth=65)            # deeper than a model file allows
    with pytest.raises(TerrathemeError, match="max_depth must be a whole number in 1..64"):
        model_bytes(train_classifier(pairs(2), opts).parts())
    train_classifier(pairs(2), opts, cache=cache)
    assert cache.misses["model"] == 1
    assert sorted(p.suffix for p in tmp_path.iterdir()) == [".samples", ".samples"]


def test_a_folder_that_cannot_be_written_costs_the_caching_not_the_training(tmp_path, target):
    (tmp_path / "file").write_bytes(b"x")
    cache = DiskCache(tmp_path / "file" / "cache")
    assert cache.unusable() == "Not a directory"
    model = train_classifier(pairs(2), OPTS, cache=cache)
    assert_same_model(model, train_classifier(pairs(2), OPTS), target)


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                    reason="giving a file to another user needs root")
def test_another_user_s_model_under_the_key_is_a_miss(tmp_path, trained, target):
    """Another model, forged whole (key, digest) by another user of a shared folder."""
    data, fitted = trained
    train_classifier(data, OPTS, cache=DiskCache(tmp_path))
    (path,) = tmp_path.glob("*.model")
    another = model_bytes(train_classifier(pairs(6, seed=4), OPTS).parts())
    path.write_bytes(_model_entry(path.name[:64], another))
    assert DiskCache(tmp_path).load(path.name[:64], "model", lambda a: a) is not None
    os.chown(path, 4242, 4242)
    cache = DiskCache(tmp_path)
    assert_same_model(train_classifier(data, OPTS, cache=cache), fitted, target)
    assert cache.misses["model"] == 1


def test_a_prepared_photo_trains_and_keys_as_its_pixels_and_mask(tmp_path):
    """convert passes the photo prepared once (issue 37): training takes it as the photo."""
    from terratheme.core.classify.photo import prepare_photo

    (photo, mask), = pairs(1)
    fo = SupervisedOptions().features
    prepared = prepare_photo(photo)
    rgba = np.dstack([photo, np.full(photo.shape[:2], 255, np.uint8)])
    rgba[:4, :4, 3] = 0
    keys = {tc.sample_key(p, mask, (1, 2, 3), fo, 2048, 0.0)
            for p in (photo, prepared, prepare_photo(rgba))}
    assert len(keys) == 2
    a = train_classifier([(photo, mask)], OPTS)
    b = train_classifier([(prepared, mask)], OPTS, cache=DiskCache(tmp_path))
    assert_same_model(a, b, prepared)
