"""The training caches' disk bound: least recently used entries go first, sizes as text."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from terratheme.core.classify import ModelCache, SampleCache
from terratheme.core.classify import cache_bound as cb
from terratheme.core.classify import keyed_store as ks
from terratheme.core.classify.cache_bound import DEFAULT_CACHE_BYTES, evict, parse_size
from terratheme.core.classify.keyed_store import KeyedStore
from terratheme.core.errors import TerrathemeError

NAMES = ("v",)


def _key(n: int) -> str:
    return f"{n:064x}"


def _parse(arrays):
    return arrays["v"]


def _fetch(store: KeyedStore, n: int, calls: list | None = None) -> np.ndarray:
    def compute():
        if calls is not None:
            calls.append(n)
        return np.full(1000, n, np.uint8)

    return store.fetch(_key(n), NAMES, _parse, compute, lambda v: {"v": v})


def _fill(folder: Path, numbers) -> int:
    """Entries for ``numbers``, oldest first (mtimes 100 s apart); the size of one."""
    store = KeyedStore(folder, ".npz", 0, "test values")
    for age, n in enumerate(numbers):
        _fetch(store, n)
        t = 1_000_000_000 + 100 * age
        os.utime(folder / f"{_key(n)}.npz", (t, t))
    sizes = {(folder / f"{_key(n)}.npz").stat().st_size for n in numbers}
    assert len(sizes) == 1
    return sizes.pop()


def _kept(folder: Path) -> set[int]:
    return {int(p.name[:64], 16) for p in folder.iterdir() if cb.is_entry(p.name)}


@pytest.mark.parametrize(("text", "expected"), [
    ("2G", 2_147_483_648), ("500M", 524_288_000), ("1.5g", 1_610_612_736), ("4096", 4096),
    ("64KiB", 65_536), (" 3 T ", 3_298_534_883_328), ("10mb", 10_485_760), (".5K", 512),
])
def test_sizes_are_read_in_binary_units(text, expected):
    assert parse_size(text) == expected


@pytest.mark.parametrize(("text", "match"), [
    ("", "must be a number of bytes"), ("lots", "must be a number of bytes"),
    ("-1G", "must be a number of bytes"), ("2X", "must be a number of bytes"),
    ("1e9", "must be a number of bytes"), ("2 G B", "must be a number of bytes"),
    ("nan", "must be a number of bytes"), ("5GG", "must be a number of bytes"),
    ("0", "must be at least one byte"), ("0.2", "must be at least one byte"),
])
def test_a_bad_size_is_one_clear_error(text, match):
    with pytest.raises(TerrathemeError, match=f"^--cache-size {match}.*{text!r}"):
        parse_size(text, "--cache-size")


def test_the_default_bound_is_two_gib():
    assert DEFAULT_CACHE_BYTES == 2 * 1024 ** 3
    assert KeyedStore(None, ".npz", 1, "x").max_bytes == DEFAULT_CACHE_BYTES
    assert SampleCache().max_bytes == ModelCache().max_bytes == 2 * 1024 ** 3


@pytest.mark.parametrize("cache", [SampleCache, ModelCache])
def test_a_bound_below_one_byte_is_refused(tmp_path, cache):
    with pytest.raises(TerrathemeError, match="must be at least one byte, not 0"):
        cache(tmp_path, max_bytes=0)


def test_the_least_recently_used_entries_go_first(tmp_path):
    size = _fill(tmp_path, [1, 2, 3])
    store = KeyedStore(tmp_path, ".npz", 0, "test values", max_bytes=3 * size)
    _fetch(store, 4)
    assert _kept(tmp_path) == {2, 3, 4}
    _fetch(store, 5)
    assert _kept(tmp_path) == {3, 4, 5}
    # A bound below all of them leaves the newest that fit.
    _fetch(KeyedStore(tmp_path, ".npz", 0, "test values", max_bytes=2 * size + 1), 6)
    assert _kept(tmp_path) == {5, 6}


@pytest.mark.parametrize("where", ["disk", "memory"])
def test_a_hit_makes_an_entry_the_most_recent(tmp_path, where):
    size = _fill(tmp_path, [1, 2, 3])
    store = KeyedStore(tmp_path, ".npz", 8, "test values", max_bytes=3 * size)
    if where == "memory":
        store.remember(_key(1), np.full(1000, 1, np.uint8))
    calls: list = []
    np.testing.assert_array_equal(_fetch(store, 1, calls), np.full(1000, 1, np.uint8))
    assert calls == [] and store.hits == 1
    _fetch(store, 4, calls)
    assert calls == [4]
    assert _kept(tmp_path) == {1, 3, 4}             # 2 was the oldest after the hit on 1


def test_the_bound_holds_after_every_write(tmp_path):
    bound = 5000
    store = KeyedStore(tmp_path, ".npz", 0, "test values", max_bytes=bound)
    for n in range(12):
        _fetch(store, n)
        assert sum(p.stat().st_size for p in tmp_path.iterdir()) <= bound
        assert n in _kept(tmp_path)
    assert 2 <= len(_kept(tmp_path)) < 12


def test_an_entry_over_the_bound_alone_stays_in_memory(tmp_path):
    _fill(tmp_path, [1])
    store = KeyedStore(tmp_path, ".npz", 8, "test values", max_bytes=900)
    calls: list = []
    _fetch(store, 2, calls)
    _fetch(store, 2, calls)
    assert calls == [2] and store.hits == 1
    assert _kept(tmp_path) == set()                 # and the old one no longer fits either


def test_only_entries_count_and_go(tmp_path):
    size = _fill(tmp_path, [1, 2])
    others = ["notes.npz", f"{_key(9)}.png", f"{_key(9)[:63]}.npz", f"{_key(0xABC).upper()}.npz",
              f".{_key(9)}.npz~tt-host-1-ab.tmp.npz", "photo.png"]
    for name in others:
        (tmp_path / name).write_bytes(bytes(10 * size))
    (tmp_path / f"{_key(8)}.npz").mkdir()
    store = KeyedStore(tmp_path, ".npz", 0, "test values", max_bytes=2 * size)
    _fetch(store, 3)
    assert _kept(tmp_path) == {2, 3, 8}
    assert all((tmp_path / name).is_file() for name in others)


def test_the_sample_and_model_entries_share_the_bound(tmp_path):
    size = _fill(tmp_path, [1, 2])                    # sample-like entries, "<key>.npz"
    models = KeyedStore(tmp_path, ".model.npz", 0, "test models", max_bytes=2 * size)
    _fetch(models, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{_key(2)}.npz",
                                                          f"{_key(3)}.model.npz"]


def test_an_entry_that_vanishes_before_reading_is_a_miss(tmp_path, monkeypatch):
    _fill(tmp_path, [1])
    real_load = np.load

    def load_after_another_process_evicted(path, **kwargs):
        Path(path).unlink()
        return real_load(path, **kwargs)

    monkeypatch.setattr(ks.np, "load", load_after_another_process_evicted)
    calls: list = []
    store = KeyedStore(tmp_path, ".npz", 8, "test values")
    np.testing.assert_array_equal(_fetch(store, 1, calls), np.full(1000, 1, np.uint8))
    assert calls == [1] and store.misses == 1


def test_an_entry_that_vanishes_from_memory_s_folder_is_still_a_hit(tmp_path):
    store = KeyedStore(tmp_path, ".npz", 8, "test values")
    _fetch(store, 1)
    (tmp_path / f"{_key(1)}.npz").unlink()
    calls: list = []
    _fetch(store, 1, calls)
    assert calls == [] and store.hits == 1 and _kept(tmp_path) == set()


def test_entries_that_vanish_while_evicting_are_skipped(tmp_path, monkeypatch):
    size = _fill(tmp_path, [1, 2, 3, 4])
    real_scandir = os.scandir
    gone = tmp_path / f"{_key(2)}.npz"

    class Listing:
        """The folder's listing, with entry 2 removed by another process once listed."""

        def __init__(self, folder):
            self.inner = real_scandir(folder)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.inner.close()

        def __iter__(self):
            for item in self.inner:
                if item.name == gone.name:
                    gone.unlink(missing_ok=True)
                yield item

    monkeypatch.setattr(cb.os, "scandir", Listing)
    assert evict(tmp_path, 2 * size) == [f"{_key(1)}.npz"]
    assert _kept(tmp_path) == {3, 4}
    # Removed between listing and removing: counted as gone, the bound still holds.
    listed = cb.entries(tmp_path)
    monkeypatch.setattr(cb, "entries", lambda folder: [(0, f"{_key(7)}.npz", size), *listed])
    assert evict(tmp_path, size) == [f"{_key(3)}.npz"]
    assert _kept(tmp_path) == {4}


def test_an_entry_that_cannot_be_removed_is_passed_over(tmp_path, monkeypatch):
    size = _fill(tmp_path, [1, 2, 3])
    real_unlink = Path.unlink

    def unlink(path, *args, **kwargs):
        if path.name == f"{_key(1)}.npz":
            raise PermissionError(13, "Permission denied")
        return real_unlink(path, *args, **kwargs)

    monkeypatch.setattr(Path, "unlink", unlink)
    assert evict(tmp_path, size) == [f"{_key(2)}.npz", f"{_key(3)}.npz"]
    assert _kept(tmp_path) == {1}


def test_a_missing_folder_has_no_entries(tmp_path):
    assert cb.entries(tmp_path / "nowhere") == []
    assert evict(tmp_path / "nowhere", 1) == []


def _churn(folder: str, seed: int, bound: int, rounds: int) -> None:
    """Fetch random keys of a small folder shared with another process (a child's job)."""
    rng = np.random.default_rng(seed)
    store = KeyedStore(folder, ".npz", 0, "test values", max_bytes=bound)
    for n in rng.integers(0, 12, rounds):
        value = _fetch(store, int(n))
        if not (value == n).all():
            raise SystemExit(3)


def test_processes_sharing_a_folder_evict_each_other_s_entries_without_errors(tmp_path):
    import multiprocessing

    size = _fill(tmp_path, [0])
    context = multiprocessing.get_context("fork")
    children = [context.Process(target=_churn, args=(str(tmp_path), seed, 3 * size, 200))
                for seed in (1, 2, 3)]
    for child in children:
        child.start()
    for child in children:
        child.join(60)
    assert [child.exitcode for child in children] == [0, 0, 0]
    assert sum(size for _, _, size in cb.entries(tmp_path)) <= 3 * size
    assert not [p for p in tmp_path.iterdir() if not cb.is_entry(p.name)]   # no temporaries
