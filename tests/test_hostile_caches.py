"""Hostile cache entries (issue 33): each is a miss, computed again, never a crash or a hang.

Entries are forged here byte by byte (:func:`forge`, the format of
core/io/disk_cache.py with a valid digest), so each case gets past the
checksum and meets the checks that matter: against the key's texture or
training, the file's kind (FIFO, symlink, another user's), and its sizes.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import shutil
import struct
import threading

import numpy as np
import pytest
from hostile_fuzz import EDITS, campaign, check_refused, run_bytes, run_cli, run_edited
from hypothesis import strategies as st
from terratheme.core.io.disk_cache import DiskCache
from terratheme.core.io.images import read_image, write_image
from terratheme.core.perspective import Camera, PreparedTexture, family_key
from test_hostile_harness import shared_reader

VIEW = Camera(height=5, pitch=8, yaw=30)


def forge(key: str, kind: str, arrays: dict[str, np.ndarray], header: dict | None = None,
          payload: bytes | None = None) -> bytes:
    """An entry's bytes: magic, header, the arrays (or ``payload``), SHA-256 of all that."""
    meta = header if header is not None else {
        "key": key, "kind": kind,
        "arrays": {n: [a.dtype.name, list(a.shape)] for n, a in arrays.items()}}
    text = json.dumps(meta).encode()
    data = payload if payload is not None else b"".join(a.tobytes() for a in arrays.values())
    body = b"TTCACHE1" + struct.pack("<I", len(text)) + text + data
    return body + hashlib.sha256(body).digest()


def _tex(dtype=np.uint8):
    return np.random.default_rng(5).integers(0, 256, (32, 48, 3)).astype(dtype)


@pytest.fixture(scope="module")
def fresh():
    """The texture's family and frame, built without a cache."""
    prepared = PreparedTexture(_tex())
    return prepared.family(), prepared.render(VIEW, (40, 24)).image


def _entry_path(folder, tex=None):
    return folder / f"{family_key(_tex() if tex is None else tex, 4, 1)}.family"


def _prepared_again(folder, fresh):
    """A texture prepared over the planted entry: a miss, the very family and frame."""
    prepared = PreparedTexture(_tex(), cache=DiskCache(folder))
    assert prepared.cache_hit is False
    np.testing.assert_array_equal(prepared.family().buf, fresh[0].buf)
    np.testing.assert_array_equal(prepared.render(VIEW, (40, 24)).image, fresh[1])
    return prepared


# -- the family (perspective) -----------------------------------------------------

@pytest.mark.parametrize("cells", [
    pytest.param(lambda total: np.zeros((1, 3), np.uint8), id="grid_1x1"),
    pytest.param(lambda total: np.zeros((total, 4), np.uint8), id="four_channels"),
    pytest.param(lambda total: np.zeros((total // 2, 3), np.uint16), id="uint16_same_bytes"),
    pytest.param(lambda total: np.zeros((total, 3), np.uint16), id="uint16"),
    pytest.param(lambda total: np.zeros((total, 3), np.float32), id="float32"),
    pytest.param(lambda total: np.zeros((total - 1, 3), np.uint8), id="one_cell_short"),
])
def test_a_family_entry_that_is_not_the_texture_s_is_a_miss(tmp_path, fresh, cells):
    path = _entry_path(tmp_path)
    path.write_bytes(forge(path.name[:64], "family", {"cells": cells(len(fresh[0].buf))}))
    _prepared_again(tmp_path, fresh)
    assert PreparedTexture(_tex(), cache=DiskCache(tmp_path)).cache_hit is True   # replaced


def test_a_float_family_entry_with_nan_is_a_miss(tmp_path):
    tex = _tex(np.float32)
    want = PreparedTexture(tex).family()
    path = _entry_path(tmp_path, tex)
    cells = want.buf.copy()
    cells[5, 1] = np.nan
    path.write_bytes(forge(path.name[:64], "family", {"cells": cells}))
    prepared = PreparedTexture(tex, cache=DiskCache(tmp_path))
    assert prepared.cache_hit is False
    np.testing.assert_array_equal(prepared.family().buf, want.buf)


def test_a_good_forged_family_entry_is_a_hit(tmp_path, fresh):
    """The baseline of the cases above: what :func:`forge` makes reads back."""
    path = _entry_path(tmp_path)
    path.write_bytes(forge(path.name[:64], "family", {"cells": fresh[0].buf}))
    assert PreparedTexture(_tex(), cache=DiskCache(tmp_path)).cache_hit is True


def test_a_poisoned_family_entry_gives_the_right_frame_from_the_cli(tmp_path):
    """Was SIGSEGV (a 1 x 1 grid under the texture's key) or a wrong frame with exit 0."""
    write_image(tmp_path / "tex.png", _tex())
    args = ["perspective", tmp_path / "tex.png", tmp_path / "o.png", "--size", "40x24"]
    plain = run_cli(*args, "--no-cache")
    assert plain.returncode == 0, plain.stderr
    want = read_image(tmp_path / "o.png")
    cache = tmp_path / "cache"
    assert run_cli(*args, "--cache-dir", cache).returncode == 0
    (path,) = cache.glob("*.family")
    path.write_bytes(forge(path.name[:64], "family", {"cells": np.full((1, 3), 9, np.uint8)}))
    proc = run_cli(*args, "--cache-dir", cache)
    assert proc.returncode == 0, proc.stderr
    assert "family cached" in proc.stdout            # a miss, rebuilt and kept
    np.testing.assert_array_equal(read_image(tmp_path / "o.png"), want)


# -- what any entry may be ---------------------------------------------------------

def _in_thread(call, seconds=20.0):
    """``call()`` in a thread; fails if it has not returned after ``seconds``."""
    done: list = []
    thread = threading.Thread(target=lambda: done.append(call()), daemon=True)
    thread.start()
    thread.join(seconds)
    assert done, f"still blocked after {seconds} s"
    return done[0]


def test_a_fifo_entry_is_a_miss_not_a_hang(tmp_path, fresh):
    path = _entry_path(tmp_path)
    os.mkfifo(path)
    try:
        _in_thread(lambda: _prepared_again(tmp_path, fresh))
    finally:
        # release a reader blocked on the FIFO (the test has failed then)
        if path.exists() and not path.is_file():
            try:
                os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:
                pass
    assert path.is_file()                             # the entry written over the FIFO


def test_a_folder_at_an_entry_s_name_is_a_miss(tmp_path, fresh):
    # It was opened as a file first: "3: Is a directory" failed the run.
    path = _entry_path(tmp_path)
    path.mkdir()
    (path / "inside").write_bytes(b"kept")
    _prepared_again(tmp_path, fresh)
    assert (path / "inside").read_bytes() == b"kept"   # left alone


def test_a_symlinked_entry_is_not_followed(tmp_path, fresh):
    outside = tmp_path / "outside"
    outside.mkdir()
    target = outside / "victim"
    target.write_bytes(forge(_entry_path(tmp_path).name[:64], "family",
                             {"cells": fresh[0].buf}))
    before = target.read_bytes()
    cache = tmp_path / "cache"
    cache.mkdir()
    _entry_path(cache).symlink_to(target)
    _prepared_again(cache, fresh)                     # a good entry, but not read through a link
    assert target.read_bytes() == before              # nor written through it
    assert not _entry_path(cache).is_symlink()


def test_eviction_removes_no_file_through_a_symlink(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "big").write_bytes(bytes(5000))
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / f"{'a' * 64}.family").symlink_to(outside / "big")
    (cache / f"{'b' * 64}.samples").symlink_to(outside)
    DiskCache(cache, max_bytes=200).store("c" * 64, "model", {"model": np.zeros(10, np.uint8)})
    assert (outside / "big").stat().st_size == 5000
    assert sorted(p.name[65:] for p in cache.iterdir()) == ["family", "model", "samples"]


def test_an_entry_is_never_unpickled(tmp_path):
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (shutil.copy, (__file__, str(marker)))

    key = "d" * 64
    for data in (pickle.dumps(Payload()), pickle.dumps({"model": Payload()})):
        (tmp_path / f"{key}.model").write_bytes(data)
        assert DiskCache(tmp_path).load(key, "model", lambda arrays: arrays) is None
        assert not marker.exists() and not (tmp_path / f"{key}.model").exists()


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                    reason="giving a file to another user needs root")
def test_another_user_s_entry_is_a_miss_and_left_alone(tmp_path, fresh):
    path = _entry_path(tmp_path)
    path.write_bytes(forge(path.name[:64], "family", {"cells": fresh[0].buf}))
    os.chown(path, 4242, 4242)
    assert DiskCache(tmp_path).load(path.name[:64], "family", lambda a: a) is None
    assert path.stat().st_uid == 4242


@pytest.mark.parametrize("header", [
    {"key": "e" * 64, "kind": "model", "arrays": {"model": ["uint8", [1 << 40]]}},
    {"key": "e" * 64, "kind": "model", "arrays": {"model": ["uint8", [1 << 41]]}},
    {"key": "e" * 64, "kind": "model", "arrays": {"model": ["uint8", [-1]]}},
    {"key": "e" * 64, "kind": "model", "arrays": {"model": ["object", [4]]}},
    {"key": "e" * 64, "kind": "model", "arrays": {"model": [["uint8"], [4]]}},
    {"key": "e" * 64, "kind": "model", "arrays": {"model": ["uint8", [True] * 4]}},
    {"key": "e" * 64, "kind": "model", "arrays": {"model": ["uint8", [1, 1, 1, 1, 4]]}},
    {"key": "f" * 64, "kind": "model", "arrays": {"model": ["uint8", [4]]}},
    {"key": "e" * 64, "kind": "samples", "arrays": {"model": ["uint8", [4]]}},
    {"key": "e" * 64, "kind": "model", "arrays": {"model": ["uint8", [4]]}, "x": 1},
    {"key": "e" * 64, "kind": "model", "arrays": [["model", "uint8", [4]]]},
])
def test_a_forged_header_is_a_miss_and_is_removed(tmp_path, header):
    path = tmp_path / f"{'e' * 64}.model"
    path.write_bytes(forge("", "", {}, header=header, payload=bytes(4)))
    assert DiskCache(tmp_path).load("e" * 64, "model", lambda arrays: arrays) is None
    assert not path.exists()


# -- fuzzing through the bounded reader ------------------------------------------------

@pytest.fixture(scope="module")
def bounded():
    return shared_reader()


@pytest.fixture(scope="module")
def sample() -> bytes:
    arrays = {"features": np.arange(24, dtype=np.float32).reshape(4, 6),
              "labels": np.array([1, 2, 1, 2], np.uint8)}
    return forge("0" * 64, "samples", arrays)


@campaign
def test_flips_and_insertions_of_an_entry(budget, bounded, sample, tmp_path):
    budget.explore(lambda edits: run_edited(bounded, "cache", sample,
                                            tmp_path / f"{'0' * 64}.samples", edits),
                   edits=EDITS)


VALUES = (st.none() | st.booleans() | st.integers(-(1 << 70), 1 << 70) | st.floats()
          | st.text(max_size=6) | st.lists(st.integers(-5, 1 << 40), max_size=5)
          | st.lists(st.sampled_from(["uint8", "float32", "x"]) | st.integers(0, 9), max_size=3))


@campaign
def test_hostile_header_values(budget, bounded, tmp_path):
    def case(changes):
        meta = {"key": "0" * 64, "kind": "samples",
                "arrays": {"features": ["float32", [4, 6]], "labels": ["uint8", [4]]}}
        for where, value in changes:
            if where in ("key", "kind", "arrays") or not isinstance(meta["arrays"], dict):
                meta[where] = value
            else:
                meta["arrays"][where] = value
        run_bytes(bounded, "cache", tmp_path / f"{'0' * 64}.samples",
                  forge("", "", {}, header=meta, payload=bytes(112)))

    budget.explore(case, changes=st.lists(st.tuples(st.sampled_from(
        ["key", "kind", "arrays", "features", "labels"]), VALUES), min_size=1, max_size=3))


def test_a_named_cache_folder_that_cannot_be_used_is_one_line_before_work(tmp_path):
    write_image(tmp_path / "tex.png", _tex())
    (tmp_path / "file").write_text("not a folder")
    proc = run_cli("perspective", tmp_path / "tex.png", tmp_path / "pv.png", "--size", "32x24",
                   "--cache-dir", tmp_path / "file" / "sub")
    check_refused(proc, "--cache-dir", "file/sub: cannot use the folder (Not a directory)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "tex.png"]


def test_an_unusable_default_cache_still_gives_the_frame(tmp_path):
    import subprocess
    import sys

    from hostile_fuzz import REPO

    write_image(tmp_path / "tex.png", _tex())
    (tmp_path / "file").write_text("not a folder")
    env = dict(os.environ, PYTHONPATH=str(REPO), XDG_CACHE_HOME=str(tmp_path / "file"))
    proc = subprocess.run([sys.executable, "-m", "terratheme.app.cli", "perspective",
                           str(tmp_path / "tex.png"), str(tmp_path / "pv.png"), "--size", "32x24"],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "note: the family cache" in proc.stdout and "the family is not kept" in proc.stdout
    assert "family cached" not in proc.stdout and (tmp_path / "pv.png").is_file()


def test_a_fifo_as_a_training_entry_does_not_block_classify(tmp_path):
    rng = np.random.default_rng(0)
    truth = np.kron(rng.integers(1, 3, (4, 6)), np.ones((16, 16), np.uint8)).astype(np.uint8)
    photo = np.where(truth[:, :, None] == 1, 60, 190) + rng.integers(0, 20, truth.shape + (3,))
    write_image(tmp_path / "photo.png", photo.astype(np.uint8))
    write_image(tmp_path / "truth.png", truth)
    cache = tmp_path / "cache"
    args = ["classify", tmp_path / "photo.png", "-o", tmp_path / "l.png", "--train",
            tmp_path / "photo.png", tmp_path / "truth.png", "--cache-dir", cache]
    assert run_cli(*args).returncode == 0
    for entry in cache.iterdir():
        entry.unlink()
        os.mkfifo(entry)
    proc = run_cli(*args, timeout=120)                # was blocked for good
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.is_file() for p in cache.iterdir()) == [True, True]
