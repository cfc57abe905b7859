"""Fuzzing the project loader within the time and memory bound.

Every case runs in :class:`test_hostile_harness.BoundedReader` (256 MiB, 2 s
CPU) and must end in a project or one line naming the file: truncations of a
small project, byte flips and insertions, hostile ZIP central-directory
fields and hostile ``.npy`` headers. The quick suite runs a small
deterministic set; ``-m slow`` runs every truncation and 1500 examples each.
"""

from __future__ import annotations

import hostile_fuzz as fuzz
import pytest
from hypothesis import strategies as st
from terratheme.core.model.project import save_project
from test_hostile_harness import npy_bytes, shared_reader
from test_hostile_project import _manifest, _members, _small_project, _write


@pytest.fixture(scope="module")
def bounded():
    return shared_reader()


@pytest.fixture(scope="module")
def sample(tmp_path_factory) -> bytes:
    path = tmp_path_factory.mktemp("sample") / "s.ttproj"
    save_project(path, _small_project())
    return path.read_bytes()


@fuzz.campaign
def test_truncations_of_a_small_project(budget, bounded, sample, tmp_path):
    assert len(sample) < 4000
    kinds = fuzz.run_truncations(bounded, "project", sample, tmp_path / "cut.ttproj", budget,
                            quick_cases=len(sample) // 5)
    assert kinds == {"error"}


@fuzz.campaign
def test_flips_and_insertions(budget, bounded, sample, tmp_path):
    budget.explore(lambda edits: fuzz.run_edited(bounded, "project", sample,
                                                 tmp_path / "mut.ttproj", edits),
                   edits=fuzz.EDITS)


@fuzz.campaign
def test_hostile_zip_directory_fields(budget, bounded, sample, tmp_path):
    budget.explore(lambda member, fields: fuzz.run_bytes(
        bounded, "project", tmp_path / "dir.ttproj",
        fuzz.hostile_directory(sample, member, fields)),
        member=st.integers(0, 8), fields=fuzz.ZIP_DIRECTORY_FIELDS)


SHAPES = st.lists(st.sampled_from([0, 1, 2, 3, 5, 65535, 1 << 31, 1 << 62, -1]) |
                  st.integers(-5, 1 << 40), max_size=4)
HEADERS = st.builds(
    lambda descr, fortran, shape, junk: (
        f"{{'descr': {descr!r}, 'fortran_order': {fortran}, 'shape': {tuple(shape)!r}, }}"
        if junk is None else junk),
    st.sampled_from(["|u1", "<u2", ">u1", "<f4", "|b1", "|O", "<c16", "V8", "<U3"]),
    st.booleans(), SHAPES,
    st.none() | st.sampled_from(["{}", "[", "{'descr': 5}", "x" * 20000, "(" * 500,
                                 "{'descr': '|u1', 'fortran_order': 1, 'shape': (2, 3)}"]))
BODY = st.binary(max_size=64)


def _run_npy(bounded, tmp_path, member, header, body):
    arrays = {member: npy_bytes(header, body)}
    layers = ["photo"] if member == "photo_npy" else []
    path = _write(tmp_path, _members(_manifest(layers=layers), **arrays), "npy.ttproj")
    fuzz.run_bytes(bounded, "project", path, path.read_bytes())


@fuzz.campaign
def test_hostile_npy_headers(budget, bounded, tmp_path):
    budget.explore(lambda member, header, body: _run_npy(bounded, tmp_path, member, header, body),
                   member=st.sampled_from(["grid_npy", "themes__000_npy", "photo_npy"]),
                   header=HEADERS, body=BODY)
