"""Hostile files in the perspective cache: each is a miss (and removed), never an exception.

Regression tests for what the campaign of issue 16 found in
:class:`core.perspective.FamilyCache` (a header nested 4000 deep was a
RecursionError, ``"k": 1e400`` or a cell count of ``Infinity`` an
OverflowError: tracebacks from ``perspective`` on a damaged cache file),
then fuzzing of a small family file through
:class:`test_hostile_harness.BoundedReader`.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest
from hostile_fuzz import (
    EDITS,
    REPO,
    campaign,
    check_refused,
    run_bytes,
    run_cli,
    run_edited,
    run_truncations,
)
from hypothesis import strategies as st
from terratheme.core.io.images import write_image
from terratheme.core.perspective import FamilyCache
from terratheme.core.perspective.cache import FORMAT_VERSION, MAGIC
from terratheme.core.perspective.family import build_family
from test_hostile_harness import shared_reader

#: the file's fixed header: magic, version, JSON length (core/perspective/cache.py)
HEADER = struct.Struct("<8sII")
GOOD = '{"dtype": "uint8", "cells": [1, 1], "grid": [1, 1], "k": 0, "so": 1}'


def _family_file(header: str | bytes, cells: bytes = b"") -> bytes:
    text = header.encode() if isinstance(header, str) else header
    body = HEADER.pack(MAGIC, FORMAT_VERSION, len(text)) + text + cells
    return body + struct.pack("<I", zlib.crc32(body))


@pytest.mark.parametrize("header", [
    "[" * 4000, '{"a": ' * 700 + "1" + "}" * 700,
    GOOD.replace('"cells": [1, 1]', '"cells": [Infinity, 1]'),
    GOOD.replace('"k": 0', '"k": 1e400'), GOOD.replace('"k": 0', '"k": ' + "9" * 4000),
    GOOD.replace('"k": 0', '"k": 0.5'), GOOD.replace('"so": 1', '"so": true'),
    GOOD.replace('"uint8"', '["uint8"]'), GOOD.replace('"uint8"', '"object"'),
    GOOD.replace('"grid": [1, 1]', '"grid": [1]'), "[]", '"x"', b"\xff\xfe", "",
])
def test_a_damaged_cache_file_is_a_miss_and_is_removed(tmp_path, header):
    cache = FamilyCache(tmp_path)
    cache.path("key").write_bytes(_family_file(header))
    assert cache.load("key") is None
    assert not cache.path("key").exists()


def test_the_crafted_baseline_is_a_family(tmp_path):
    cache = FamilyCache(tmp_path)
    cache.path("key").write_bytes(_family_file(GOOD, b"\x07"))
    family = cache.load("key")
    assert family is not None and family.buf.tolist() == [[7]]


@pytest.fixture(scope="module")
def sample(tmp_path_factory) -> bytes:
    folder = tmp_path_factory.mktemp("family")
    texels = np.random.default_rng(4).integers(0, 255, (8, 8, 3)).astype(np.float32)
    FamilyCache(folder).store("s", build_family(texels, 2, 2))
    data = (folder / "s.ttfamily").read_bytes()
    assert len(data) < 8000
    return data


@pytest.fixture(scope="module")
def bounded():
    return shared_reader()


@campaign
def test_truncations_of_a_family_file(budget, bounded, sample, tmp_path):
    assert run_truncations(bounded, "family", sample, tmp_path / "c.ttfamily", budget) == {"ok"}


@campaign
def test_flips_and_insertions(budget, bounded, sample, tmp_path):
    budget.explore(lambda edits: run_edited(bounded, "family", sample, tmp_path / "m.ttfamily",
                                            edits), edits=EDITS)


VALUES = (st.none() | st.booleans() | st.integers(-(1 << 70), 1 << 70) | st.floats()
          | st.text(max_size=6) | st.lists(st.integers(-5, 1 << 40), max_size=3))


def _hostile_header(changes) -> bytes:
    meta = json.loads(GOOD)
    for key, value in changes:
        meta[key] = value
    return _family_file(json.dumps(meta), b"\0" * 16)


@campaign
def test_hostile_header_values(budget, bounded, tmp_path):
    budget.explore(lambda changes: run_bytes(bounded, "family", tmp_path / "h.ttfamily",
                                             _hostile_header(changes)),
                   changes=st.lists(st.tuples(st.sampled_from(["dtype", "cells", "grid", "k",
                                                               "so"]), VALUES),
                                    min_size=1, max_size=3))


# -- a cache folder that cannot be used -----------------------------------------

def test_a_cache_that_cannot_be_written_costs_the_caching_not_the_frame(tmp_path):
    (tmp_path / "file").write_text("not a folder")
    family = build_family(np.zeros((8, 8, 3), np.float32), 2, 1)
    assert FamilyCache(tmp_path / "file" / "sub").store("k", family) is False
    assert FamilyCache(tmp_path / "ok").store("k", family) is True


@pytest.fixture(scope="module")
def texture(tmp_path_factory):
    path = tmp_path_factory.mktemp("tex") / "tex.png"
    write_image(path, np.random.default_rng(0).integers(0, 255, (32, 32, 3)).astype(np.uint8))
    return path


def test_a_named_cache_folder_that_cannot_be_used_is_one_line_before_work(texture, tmp_path):
    (tmp_path / "file").write_text("not a folder")
    proc = run_cli("perspective", texture, tmp_path / "pv.png", "--size", "32x24",
                   "--cache-dir", tmp_path / "file" / "sub")
    check_refused(proc, "--cache-dir", "file/sub: cannot use the folder (Not a directory)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_an_unusable_default_cache_still_gives_the_frame(texture, tmp_path):
    (tmp_path / "file").write_text("not a folder")
    env = dict(os.environ, PYTHONPATH=str(REPO), XDG_CACHE_HOME=str(tmp_path / "file"))
    proc = subprocess.run([sys.executable, "-m", "terratheme.app.cli", "perspective", str(texture),
                           str(tmp_path / "pv.png"), "--size", "32x24"], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "note: the family cache" in proc.stdout and "the family is not kept" in proc.stdout
    assert "family cached" not in proc.stdout and (tmp_path / "pv.png").is_file()
