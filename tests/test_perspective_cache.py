"""Issue 18: prefiltered families kept in the disk cache (core/perspective/render.py)."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.io.disk_cache import DiskCache
from terratheme.core.perspective import Camera, FilterOptions, PreparedTexture, family_key


def _tex(seed=0, shape=(32, 48, 3), dtype=np.uint8):
    return np.random.default_rng(seed).integers(0, 256, shape).astype(dtype)


def _same_family(a, b):
    np.testing.assert_array_equal(a.buf, b.buf)
    np.testing.assert_array_equal(a.start, b.start)
    np.testing.assert_array_equal(a.count, b.count)
    assert (a.grid_size, a.max_lambda_log2, a.skew_oversampling) == (
        b.grid_size, b.max_lambda_log2, b.skew_oversampling)


def test_key_follows_content_shape_type_and_options():
    tex = _tex()
    key = family_key(tex, 4, 1)
    assert key == family_key(tex.copy(), 4, 1)
    changed = tex.copy()
    changed[3, 4, 1] ^= 1
    others = {family_key(changed, 4, 1), family_key(tex, 3, 1), family_key(tex, 4, 2),
              family_key(tex.reshape(48, 32, 3), 4, 1), family_key(tex.astype(np.uint16), 4, 1)}
    assert key not in others and len(others) == 5


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_second_prepare_loads_the_family_and_renders_the_same(tmp_path, dtype):
    tex = _tex(2, dtype=dtype)
    cache = DiskCache(tmp_path)
    first = PreparedTexture(tex, cache=cache)
    assert first.cache_hit is False
    second = PreparedTexture(tex, cache=DiskCache(tmp_path))
    assert second.cache_hit is True
    _same_family(first.family(), second.family())
    cam = Camera(height=5, pitch=8, yaw=30)
    np.testing.assert_array_equal(first.render(cam, (40, 24)).image,
                                  second.render(cam, (40, 24)).image)
    # other options are another family
    third = PreparedTexture(tex, FilterOptions(max_anisotropy=8), cache=cache)
    assert third.cache_hit is False
    assert len(list(tmp_path.glob("*.family"))) == 2


@pytest.mark.parametrize("how", ["flip", "truncate", "grow", "magic", "empty"])
def test_a_damaged_entry_is_a_miss_and_is_rebuilt(tmp_path, how):
    tex = _tex(3)
    good = PreparedTexture(tex, cache=DiskCache(tmp_path)).family()
    (path,) = tmp_path.glob("*.family")
    data = bytearray(path.read_bytes())
    if how == "flip":
        data[len(data) // 2] ^= 0x10
    elif how == "truncate":
        data = data[: len(data) - 7]
    elif how == "grow":
        data += b"\0" * 3
    elif how == "magic":
        data[:8] = b"NOTCACHE"
    else:
        data = bytearray()
    path.write_bytes(bytes(data))
    again = PreparedTexture(tex, cache=DiskCache(tmp_path))
    assert again.cache_hit is False
    _same_family(again.family(), good)
    assert PreparedTexture(tex, cache=DiskCache(tmp_path)).cache_hit is True   # replaced


def test_a_family_larger_than_the_bound_is_not_stored(tmp_path):
    tex = _tex(4)
    prepared = PreparedTexture(tex, cache=DiskCache(tmp_path, max_bytes=1000))
    assert prepared.family().nbytes > 1000
    assert prepared.cache_hit is False and not list(tmp_path.iterdir())
