"""The training-sample cache: the same samples and model, from memory or disk, by content."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from classify_cases import block_pairs as pairs
from terratheme.core.classify import SupervisedOptions, train_classifier
from terratheme.core.classify.sample_cache import SampleCache, sample_key
from terratheme.core.classify.supervised import collect_samples


def test_cached_samples_are_identical_to_computed_ones(tmp_path):
    data = pairs()
    opts = SupervisedOptions()
    x0, y0 = collect_samples(data, opts)
    cache = SampleCache(tmp_path)
    x1, y1 = collect_samples(data, opts, cache)
    assert (cache.hits, cache.misses) == (0, 3)
    x2, y2 = collect_samples(data, opts, cache)           # from memory
    x3, y3 = collect_samples(data, opts, SampleCache(tmp_path))   # from disk
    assert cache.hits == 3
    # From memory and from disk: bit for bit the samples computed on the miss.
    for x, y in ((x2, y2), (x3, y3)):
        np.testing.assert_array_equal(x, x1)
        np.testing.assert_array_equal(y, y1)
    # Computing features twice agrees to float rounding only (OpenCV's vector paths
    # depend on the buffers' alignment), so the miss matches a fresh computation so.
    np.testing.assert_array_equal(y1, y0)
    np.testing.assert_allclose(x1, x0, rtol=1e-6, atol=1e-5)
    assert len(list(tmp_path.glob("*.npz"))) == 3


def test_a_cached_training_gives_the_same_model():
    data = pairs(2, seed=1)
    cache = SampleCache()
    a = train_classifier(data, cache=cache)
    b = train_classifier(data, cache=cache)
    c = train_classifier(data)
    target = pairs(1, seed=2)[0][0]
    assert cache.hits == 2
    # The same samples, so the same forest; an uncached training differs by float rounding.
    for name in ("feature", "threshold", "left", "right", "value"):
        np.testing.assert_array_equal(getattr(a.forest, name), getattr(b.forest, name))
    np.testing.assert_array_equal(a.predict(target).labels, b.predict(target).labels)
    assert (a.predict(target).labels == c.predict(target).labels).mean() > 0.999


def test_the_key_changes_with_anything_the_samples_depend_on():
    (photo, mask), = pairs(1)
    fo = SupervisedOptions().features
    base = sample_key(photo, mask, (1, 2, 3), fo, 2048, 0.0)
    assert base == sample_key(photo.copy(), mask.copy(), [1, 2, 3], fo, 2048, 0.0)
    other_photo = photo.copy()
    other_photo[0, 0, 0] ^= 1
    other_mask = mask.copy()
    other_mask[5, 5] = 0
    variants = [
        sample_key(other_photo, mask, (1, 2, 3), fo, 2048, 0.0),
        sample_key(photo, other_mask, (1, 2, 3), fo, 2048, 0.0),
        sample_key(photo, mask, (1, 2), fo, 2048, 0.0),
        sample_key(photo, mask, (1, 2, 3), replace(fo, relative=not fo.relative), 2048, 0.0),
        sample_key(photo, mask, (1, 2, 3), fo, 1024, 0.0),
        sample_key(photo, mask, (1, 2, 3), fo, 2048, 5.0),
        sample_key(photo[:, :, :2].copy(), mask, (1, 2, 3), fo, 2048, 0.0),
    ]
    assert len({base, *variants}) == len(variants) + 1


@pytest.mark.parametrize("damage", ["truncate", "garbage", "other_key", "wrong_width"])
def test_a_damaged_entry_is_computed_again(tmp_path, damage):
    data = pairs(1)
    opts = SupervisedOptions()
    x0, y0 = collect_samples(data, opts, SampleCache(tmp_path))
    (path,) = tmp_path.glob("*.npz")
    if damage == "truncate":
        path.write_bytes(path.read_bytes()[:100])
    elif damage == "garbage":
        path.write_bytes(b"\x00" * 64)
    else:
        # A well-formed entry that is not this key's samples.
        key = path.stem if damage == "wrong_width" else "0" * 64
        width = x0.shape[1] + (1 if damage == "wrong_width" else 0)
        np.savez(path, key=np.frombuffer(key.encode(), np.uint8),
                 features=np.zeros((len(y0), width), np.float32), labels=y0)
    cache = SampleCache(tmp_path)
    x1, y1 = collect_samples(data, opts, cache)
    assert cache.misses == 1
    np.testing.assert_allclose(x1, x0, rtol=1e-6, atol=1e-5)
    np.testing.assert_array_equal(y1, y0)
    # ... and the entry was replaced by a good one.
    again = SampleCache(tmp_path)
    collect_samples(data, opts, again)
    assert again.hits == 1
