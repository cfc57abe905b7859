"""The disk cache's bound (core/io/disk_cache.py): least recently used entries go first."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.io import disk_cache as dc
from terratheme.core.io.disk_cache import DEFAULT_CACHE_BYTES, DiskCache


def _key(n: int) -> str:
    return f"{n:064x}"


def _value(n: int) -> dict[str, np.ndarray]:
    return {"v": np.full(1000, n, np.uint8)}


def _get(cache: DiskCache, n: int, calls: list | None = None) -> np.ndarray:
    """The value of key ``n`` (kind ``t``), computed (and noted in ``calls``) on a miss."""
    def compute():
        if calls is not None:
            calls.append(n)
        return _value(n)["v"]

    return cache.fetch(_key(n), "t", lambda a: a["v"], compute, lambda v: {"v": v})


def _fill(folder: Path, numbers, kind: str = "t") -> int:
    """Entries for ``numbers``, oldest first (mtimes 100 s apart); the size of one."""
    cache = DiskCache(folder)
    for age, n in enumerate(numbers):
        assert cache.store(_key(n), kind, _value(n))
        t = 1_000_000_000 + 100 * age
        os.utime(folder / f"{_key(n)}.{kind}", (t, t))
    sizes = {(folder / f"{_key(n)}.{kind}").stat().st_size for n in numbers}
    assert len(sizes) == 1
    return sizes.pop()


def _kept(folder: Path) -> set[int]:
    """Keys of the regular entries in ``folder``."""
    return {int(p.name[:64], 16) for p in folder.iterdir()
            if re.fullmatch(r"[0-9a-f]{64}\.[a-z]+", p.name) and p.is_file()}


def test_a_bound_below_one_byte_is_refused(tmp_path):
    with pytest.raises(TerrathemeError, match="must be at least one byte, not 0"):
        DiskCache(tmp_path, max_bytes=0)


@pytest.mark.parametrize(("over", "kept"), [(0, {1, 2}), (1, {2})])
def test_the_default_bound_is_applied(tmp_path, over, kept):
    """A folder whose entries reach the default bound loses its oldest one (a sparse file
    stands for an old entry of almost 2 GiB)."""
    size = _fill(tmp_path, [2])
    old = tmp_path / f"{_key(1)}.t"
    with open(old, "wb") as f:
        f.truncate(DEFAULT_CACHE_BYTES - 2 * size + over)
    os.utime(old, (1, 1))
    DiskCache(tmp_path).store(_key(3), "t", _value(3))
    assert _kept(tmp_path) == kept | {3}


def test_the_least_recently_used_entries_go_first(tmp_path):
    size = _fill(tmp_path, [1, 2, 3])
    cache = DiskCache(tmp_path, max_bytes=3 * size)
    _get(cache, 4)
    assert _kept(tmp_path) == {2, 3, 4}
    _get(cache, 5)
    assert _kept(tmp_path) == {3, 4, 5}
    # A bound below all of them leaves the newest that fit.
    _get(DiskCache(tmp_path, max_bytes=2 * size + 1), 6)
    assert _kept(tmp_path) == {5, 6}


def test_a_hit_makes_an_entry_the_most_recent(tmp_path):
    size = _fill(tmp_path, [1, 2, 3])
    cache = DiskCache(tmp_path, max_bytes=3 * size)
    calls: list = []
    np.testing.assert_array_equal(_get(cache, 1, calls), _value(1)["v"])
    assert calls == [] and cache.hits["t"] == 1
    _get(cache, 4, calls)
    assert calls == [4]
    assert _kept(tmp_path) == {1, 3, 4}             # 2 was the oldest after the hit on 1


def test_the_bound_holds_after_every_write(tmp_path):
    bound = 5000
    cache = DiskCache(tmp_path, max_bytes=bound)
    for n in range(12):
        _get(cache, n)
        assert sum(p.stat().st_size for p in tmp_path.iterdir()) <= bound
        assert n in _kept(tmp_path)
    assert 2 <= len(_kept(tmp_path)) < 12


def test_an_entry_over_the_bound_alone_is_not_written(tmp_path):
    cache = DiskCache(tmp_path, max_bytes=900)
    calls: list = []
    _get(cache, 2, calls)
    _get(cache, 2, calls)
    assert calls == [2, 2] and not list(tmp_path.iterdir())


def test_only_entries_count_and_go(tmp_path):
    size = _fill(tmp_path, [1, 2])
    others = ["notes.t", f"{_key(9)}.T", f"{_key(9)[:63]}.t", f"{_key(0xABC).upper()}.t",
              f".{_key(9)}.t.0123456789abcdef.tmp", f"{_key(9)}.t.npz", "photo.png"]
    for name in others:
        (tmp_path / name).write_bytes(bytes(10 * size))
    (tmp_path / f"{_key(8)}.t").mkdir()
    _get(DiskCache(tmp_path, max_bytes=2 * size), 3)
    assert _kept(tmp_path) == {2, 3}
    assert all((tmp_path / name).is_file() for name in others)
    assert (tmp_path / f"{_key(8)}.t").is_dir()


def test_a_killed_run_s_temporary_goes_once_stale(tmp_path):
    fresh, stale = (tmp_path / f".{_key(n)}.t.0123456789abcdef.tmp" for n in (1, 2))
    fresh.write_bytes(b"x")
    stale.write_bytes(b"x")
    os.utime(stale, (1, 1))
    _get(DiskCache(tmp_path), 3)
    assert fresh.exists() and not stale.exists()


def test_every_kind_shares_the_bound(tmp_path):
    size = _fill(tmp_path, [1, 2], kind="samples")
    DiskCache(tmp_path, max_bytes=2 * size).store(_key(3), "model", _value(3))
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{_key(2)}.samples",
                                                          f"{_key(3)}.model"]


def test_an_entry_that_vanishes_before_reading_is_a_miss(tmp_path, monkeypatch):
    _fill(tmp_path, [1])
    real_open = os.open

    def open_after_another_process_evicted(path, *args, **kwargs):
        Path(path).unlink(missing_ok=True)
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(dc.os, "open", open_after_another_process_evicted)
    calls: list = []
    cache = DiskCache(tmp_path)
    np.testing.assert_array_equal(_get(cache, 1, calls), _value(1)["v"])
    assert calls == [1] and cache.misses["t"] == 1


def test_entries_that_vanish_while_evicting_are_skipped(tmp_path, monkeypatch):
    size = _fill(tmp_path, [1, 2, 3, 4])
    real_scandir = os.scandir
    gone = tmp_path / f"{_key(2)}.t"

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

    monkeypatch.setattr(dc.os, "scandir", Listing)
    assert DiskCache(tmp_path, 2 * size).evict() == [f"{_key(1)}.t"]
    assert _kept(tmp_path) == {3, 4}
    # Removed between listing and removing: counted as gone, the bound still holds.
    listed = dc.entries(tmp_path)
    monkeypatch.setattr(dc, "entries", lambda folder: [(0, f"{_key(7)}.t", size), *listed])
    assert DiskCache(tmp_path, size).evict() == [f"{_key(3)}.t"]
    assert _kept(tmp_path) == {4}


def test_an_entry_that_cannot_be_removed_is_passed_over(tmp_path, monkeypatch):
    size = _fill(tmp_path, [1, 2, 3])
    real_unlink = Path.unlink

    def unlink(path, *args, **kwargs):
        if path.name == f"{_key(1)}.t":
            raise PermissionError(13, "Permission denied")
        return real_unlink(path, *args, **kwargs)

    monkeypatch.setattr(Path, "unlink", unlink)
    assert DiskCache(tmp_path, size).evict() == [f"{_key(2)}.t", f"{_key(3)}.t"]
    assert _kept(tmp_path) == {1}


def test_a_missing_folder_has_no_entries(tmp_path):
    assert dc.entries(tmp_path / "nowhere") == []
    assert DiskCache(tmp_path / "nowhere", 1).evict() == []


def test_a_folder_that_cannot_be_written_costs_the_caching(tmp_path):
    (tmp_path / "file").write_text("not a folder")
    assert DiskCache(tmp_path / "file" / "sub").store(_key(1), "t", _value(1)) is False
    assert DiskCache(tmp_path / "ok").store(_key(1), "t", _value(1)) is True


def _churn(folder: str, seed: int, bound: int, rounds: int) -> None:
    """Fetch random keys of a small folder shared with another process (a child's job)."""
    rng = np.random.default_rng(seed)
    cache = DiskCache(folder, max_bytes=bound)
    for n in rng.integers(0, 12, rounds):
        value = _get(cache, int(n))
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
    assert sum(size for _, _, size in dc.entries(tmp_path)) <= 3 * size
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]   # no temporaries
