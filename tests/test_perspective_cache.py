"""Issue 18: the on-disk cache of prefiltered families (core/perspective/cache.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from terratheme.core.perspective import (
    Camera,
    FamilyCache,
    FilterOptions,
    PreparedTexture,
    family_key,
)
from terratheme.core.perspective.family import build_family


def _tex(seed=0, shape=(32, 48, 3)):
    return np.random.default_rng(seed).integers(0, 256, shape, dtype=np.uint8)


def _same_family(a, b):
    np.testing.assert_array_equal(a.buf, b.buf)
    np.testing.assert_array_equal(a.start, b.start)
    np.testing.assert_array_equal(a.count, b.count)
    assert (a.grid_size, a.max_lambda_log2, a.skew_oversampling) == (
        b.grid_size, b.max_lambda_log2, b.skew_oversampling)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_store_then_load_gives_the_same_family(tmp_path, dtype):
    fam = build_family(np.random.default_rng(1).random((16, 32, 2)).astype(np.float32) * 200,
                       3, 2, dtype=dtype)
    cache = FamilyCache(tmp_path)
    cache.store("k1", fam)
    _same_family(cache.load("k1"), fam)
    assert cache.load("other") is None


def test_key_follows_content_shape_type_and_options():
    tex = _tex()
    key = family_key(tex, 4, 1)
    assert key == family_key(tex.copy(), 4, 1)
    changed = tex.copy()
    changed[3, 4, 1] ^= 1
    others = {family_key(changed, 4, 1), family_key(tex, 3, 1), family_key(tex, 4, 2),
              family_key(tex.reshape(48, 32, 3), 4, 1), family_key(tex.astype(np.uint16), 4, 1)}
    assert key not in others and len(others) == 5


def test_second_prepare_loads_the_family_and_renders_the_same(tmp_path):
    tex = _tex(2)
    cache = FamilyCache(tmp_path)
    first = PreparedTexture(tex, cache=cache)
    assert first.cache_hit is False
    second = PreparedTexture(tex, cache=cache)
    assert second.cache_hit is True
    _same_family(first.family(), second.family())
    cam = Camera(height=5, pitch=8, yaw=30)
    np.testing.assert_array_equal(first.render(cam, (40, 24)).image,
                                  second.render(cam, (40, 24)).image)
    # other options are another family
    third = PreparedTexture(tex, FilterOptions(max_anisotropy=8), cache=cache)
    assert third.cache_hit is False
    assert len(list(tmp_path.glob("*.ttfamily"))) == 2


def _damage(path, how):
    data = bytearray(path.read_bytes())
    if how == "flip":
        data[len(data) // 2] ^= 0x10
    elif how == "truncate":
        data = data[: len(data) - 7]
    elif how == "grow":
        data += b"\0" * 3
    elif how == "magic":
        data[:8] = b"NOTAFAMI"
    elif how == "header":
        i = data.index(b'"grid"')
        data[i + 9 : i + 11] = b"99"
    elif how == "empty":
        data = bytearray()
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("how", ["flip", "truncate", "grow", "magic", "header", "empty"])
def test_a_damaged_file_is_a_miss_and_is_rebuilt(tmp_path, how):
    tex = _tex(3)
    cache = FamilyCache(tmp_path)
    good = PreparedTexture(tex, cache=cache).family()
    (path,) = tmp_path.glob("*.ttfamily")
    _damage(path, how)
    key = path.name.removesuffix(".ttfamily")
    assert cache.load(key) is None
    assert not path.exists()
    again = PreparedTexture(tex, cache=cache)
    assert again.cache_hit is False
    _same_family(again.family(), good)
    assert cache.load(key) is not None


def test_the_folder_stays_within_its_bound_least_recently_used_first(tmp_path):
    fams = [build_family(np.full((16, 16, 3), k, np.float32), 2, 1, dtype=np.uint8)
            for k in range(4)]
    size = fams[0].nbytes
    cache = FamilyCache(tmp_path, max_bytes=3 * size + 3 * 200)
    for k, fam in enumerate(fams[:3]):
        cache.store(f"f{k}", fam)
        os.utime(cache.path(f"f{k}"), (1000 + k, 1000 + k))
    # f0 used last: f1 is now the least recently used
    assert cache.load("f0") is not None
    cache.store("f3", fams[3])
    assert cache.load("f1") is None
    assert all(cache.load(f"f{k}") is not None for k in (0, 2, 3))
    total = sum(p.stat().st_size for p in tmp_path.glob("*.ttfamily"))
    assert total <= cache.max_bytes


def test_a_family_larger_than_the_bound_is_not_stored(tmp_path):
    fam = build_family(np.zeros((32, 32, 3), np.float32), 3, 1, dtype=np.uint8)
    cache = FamilyCache(tmp_path, max_bytes=fam.nbytes // 2)
    cache.store("big", fam)
    assert cache.load("big") is None and not list(tmp_path.glob("*"))
