"""Fuzzing the project loader within the time and memory bound.

Every case runs in :class:`test_hostile_harness.BoundedReader` (256 MiB, 2 s
CPU) and must end in a project or one line naming the file: truncations of a
small project, byte flips and insertions, hostile ZIP central-directory
fields and hostile ``.npy`` headers. The quick suite runs a small
deterministic set; ``-m slow`` runs every truncation and 1500 examples each.
"""

from __future__ import annotations

import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_hostile_harness import check_bounded, npy_bytes, shared_reader
from test_hostile_project import _manifest, _members, _small_project, _write

from core.model.project import save_project

QUICK = settings(max_examples=25, derandomize=True, database=None, deadline=None,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
LONG = settings(max_examples=1500, database=None, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def bounded():
    return shared_reader()


@pytest.fixture(scope="module")
def sample(tmp_path_factory) -> bytes:
    path = tmp_path_factory.mktemp("sample") / "s.ttproj"
    save_project(path, _small_project())
    return path.read_bytes()


def _truncations(bounded, sample, tmp_path, step: int) -> None:
    assert len(sample) < 4000
    path = tmp_path / "cut.ttproj"
    kinds = set()
    for n in range(0, len(sample), step):
        path.write_bytes(sample[:n])
        outcome = bounded.run("project", path)
        check_bounded(outcome, path)
        kinds.add(outcome.kind)
    assert kinds == {"error"}


def test_truncations_of_a_small_project(bounded, sample, tmp_path):
    _truncations(bounded, sample, tmp_path, step=5)


@pytest.mark.slow
def test_every_truncation_of_a_small_project(bounded, sample, tmp_path):
    _truncations(bounded, sample, tmp_path, step=1)


def _mutate(data: bytes, edits: list[tuple[int, int, bytes]]) -> bytes:
    out = bytearray(data)
    for pos, flip, insert in edits:
        pos %= max(len(out), 1)
        out[pos] ^= flip or 0xFF
        out[pos:pos] = insert
    return bytes(out)


EDITS = st.lists(st.tuples(st.integers(0, 1 << 16), st.integers(0, 255),
                           st.binary(max_size=8)), min_size=1, max_size=4)


def _run_mutation(bounded, sample, tmp_path, edits):
    path = tmp_path / "mut.ttproj"
    path.write_bytes(_mutate(sample, edits))
    check_bounded(bounded.run("project", path), path)


@QUICK
@given(edits=EDITS)
def test_flips_and_insertions(bounded, sample, tmp_path, edits):
    _run_mutation(bounded, sample, tmp_path, edits)


@pytest.mark.slow
@LONG
@given(edits=EDITS)
def test_flips_and_insertions_long(bounded, sample, tmp_path, edits):
    _run_mutation(bounded, sample, tmp_path, edits)


FIELDS = st.lists(st.tuples(st.sampled_from(["file_size", "compressed", "method", "flags",
                                             "offset", "name_length", "entries"]),
                            st.sampled_from([0, 1, 7, 255, 0xFFFF, 0x7FFFFFFF, 0xFFFFFFFF])
                            | st.integers(0, 0xFFFFFFFF)),
                  min_size=1, max_size=3)
_CD_FIELD = {"method": (10, "<H"), "flags": (8, "<H"), "compressed": (20, "<I"),
             "file_size": (24, "<I"), "name_length": (28, "<H"), "offset": (42, "<I")}


def _hostile_directory(sample: bytes, member: int, fields) -> bytes:
    """The sample with central-directory fields of one member (or the entry count) replaced."""
    data = bytearray(sample)
    end = data.rindex(b"PK\x05\x06")
    starts = []
    pos = struct.unpack_from("<I", data, end + 16)[0]
    while data[pos:pos + 4] == b"PK\x01\x02":
        starts.append(pos)
        n, m, k = struct.unpack_from("<HHH", data, pos + 28)
        pos += 46 + n + m + k
    for name, value in fields:
        if name == "entries":
            struct.pack_into("<HH", data, end + 8, value & 0xFFFF, value & 0xFFFF)
            continue
        off, fmt = _CD_FIELD[name]
        struct.pack_into(fmt, data, starts[member % len(starts)] + off,
                         value & (0xFFFF if fmt == "<H" else 0xFFFFFFFF))
    return bytes(data)


def _run_directory(bounded, sample, tmp_path, member, fields):
    path = tmp_path / "dir.ttproj"
    path.write_bytes(_hostile_directory(sample, member, fields))
    check_bounded(bounded.run("project", path), path)


@QUICK
@given(member=st.integers(0, 8), fields=FIELDS)
def test_hostile_zip_directory_fields(bounded, sample, tmp_path, member, fields):
    _run_directory(bounded, sample, tmp_path, member, fields)


@pytest.mark.slow
@LONG
@given(member=st.integers(0, 8), fields=FIELDS)
def test_hostile_zip_directory_fields_long(bounded, sample, tmp_path, member, fields):
    _run_directory(bounded, sample, tmp_path, member, fields)


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
    check_bounded(bounded.run("project", path), path)


@QUICK
@given(member=st.sampled_from(["grid_npy", "themes__000_npy", "photo_npy"]),
       header=HEADERS, body=BODY)
def test_hostile_npy_headers(bounded, tmp_path, member, header, body):
    _run_npy(bounded, tmp_path, member, header, body)


@pytest.mark.slow
@LONG
@given(member=st.sampled_from(["grid_npy", "themes__000_npy", "photo_npy"]),
       header=HEADERS, body=BODY)
def test_hostile_npy_headers_long(bounded, tmp_path, member, header, body):
    _run_npy(bounded, tmp_path, member, header, body)
