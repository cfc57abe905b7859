"""What every hostile-file campaign shares: budgets, byte edits, truncation runs, the CLI check.

A campaign runs twice: ``quick`` in the default suite (25 derandomised
examples, a truncation every few bytes) and ``long`` under ``-m slow`` (1000
examples, every truncation). A test takes the ``budget`` parameter of
:data:`campaign` and hands its case function to :meth:`Budget.explore` (a
hypothesis run) or walks :meth:`Budget.cuts`::

    @campaign
    def test_flips(budget, bounded, sample, tmp_path):
        budget.explore(lambda edits: run_edited(bounded, "project", sample,
                                                tmp_path / "m.ttproj", edits), edits=EDITS)

Each case runs in :class:`test_hostile_harness.BoundedReader` (its memory
and time bound) and is checked by :func:`test_hostile_harness.check_bounded`.
:func:`run_cli` runs the real command line in a subprocess and checks what a
user sees on bad input: status 2, one line on stderr, no traceback.
"""

from __future__ import annotations

import functools
import os
import re
import struct
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_hostile_harness import BoundedReader, Outcome, check_bounded

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Budget:
    """How hard one run of a campaign tries."""

    name: str
    examples: int
    every_byte: bool

    def explore(self, case: Callable[..., object], /, **strategies) -> None:
        """Run ``case`` on ``examples`` draws of ``strategies`` (keyword arguments)."""
        budget = settings(max_examples=self.examples, derandomize=not self.every_byte,
                          database=None, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])

        @functools.wraps(case)
        def run(**drawn) -> None:
            case(**drawn)  # what it returns is not hypothesis's business

        budget(given(**strategies)(run))()

    def cuts(self, size: int, quick_cases: int = 120) -> range:
        """The truncation lengths to try of a ``size``-byte file."""
        return range(0, size, 1 if self.every_byte else max(1, size // quick_cases))


QUICK = Budget("quick", 25, every_byte=False)
LONG = Budget("long", 1000, every_byte=True)
#: parametrize a test over both budgets (the long one is ``@pytest.mark.slow``)
campaign = pytest.mark.parametrize("budget", [
    pytest.param(QUICK, id="quick"), pytest.param(LONG, id="long", marks=pytest.mark.slow)])

#: up to four edits: flip the byte at a position (by a mask; 0 means 0xFF), insert bytes there
EDITS = st.lists(st.tuples(st.integers(0, 1 << 16), st.integers(0, 255),
                           st.binary(max_size=8)), min_size=1, max_size=4)


#: central-directory fields of a ZIP member (or the entry count) and values to put there
ZIP_DIRECTORY_FIELDS = st.lists(
    st.tuples(st.sampled_from(["file_size", "compressed", "method", "flags", "offset",
                               "name_length", "entries"]),
              st.sampled_from([0, 1, 7, 255, 0xFFFF, 0x7FFFFFFF, 0xFFFFFFFF])
              | st.integers(0, 0xFFFFFFFF)),
    min_size=1, max_size=3)
_CD_FIELD = {"method": (10, "<H"), "flags": (8, "<H"), "compressed": (20, "<I"),
             "file_size": (24, "<I"), "name_length": (28, "<H"), "offset": (42, "<I")}


def hostile_directory(sample: bytes, member: int, fields) -> bytes:
    """The ZIP ``sample`` with central-directory fields of one member (or the entry count)
    replaced, as :data:`ZIP_DIRECTORY_FIELDS` draws them."""
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


def mutate(data: bytes, edits: list[tuple[int, int, bytes]]) -> bytes:
    """``data`` with each edit of :data:`EDITS` applied in turn."""
    out = bytearray(data)
    for pos, flip, insert in edits:
        pos %= max(len(out), 1)
        if out:
            out[pos] ^= flip or 0xFF
        out[pos:pos] = insert
    return bytes(out)


def run_bytes(bounded: BoundedReader, reader: str, path: Path, data: bytes) -> Outcome:
    """Write ``data`` to ``path``, run ``reader`` on it, check the bounds; the outcome."""
    path.write_bytes(data)
    outcome = bounded.run(reader, path)
    check_bounded(outcome, path)
    return outcome


def run_edited(bounded: BoundedReader, reader: str, data: bytes, path: Path, edits) -> None:
    """:func:`run_bytes` on ``data`` edited by :func:`mutate`."""
    run_bytes(bounded, reader, path, mutate(data, edits))


def run_truncations(bounded: BoundedReader, reader: str, data: bytes, path: Path,
                    budget: Budget, quick_cases: int = 120) -> set[str]:
    """Every truncation :meth:`Budget.cuts` gives of ``data``; the outcome kinds seen."""
    return {run_bytes(bounded, reader, path, data[:n]).kind
            for n in budget.cuts(len(data), quick_cases)}


def run_cli(*args: str | os.PathLike, timeout: float = 180.0) -> subprocess.CompletedProcess:
    """``python -m terratheme.app.cli ARGS`` from this checkout; stdout and stderr as
    text, with their carriage returns kept (a progress bar redraws its line with them)."""
    proc = subprocess.run([sys.executable, "-m", "terratheme.app.cli", *map(str, args)], cwd=REPO,
                          capture_output=True, timeout=timeout,
                          env=dict(os.environ, PYTHONPATH=str(REPO)))
    return subprocess.CompletedProcess(proc.args, proc.returncode,
                                       proc.stdout.decode(errors="replace"),
                                       proc.stderr.decode(errors="replace"))


def check_refused(proc: subprocess.CompletedProcess, *needles: str) -> str:
    """A CLI run refused its input as the brief says: status 2, one error line, no traceback;
    the line (what a terminal shows: after a progress bar's last carriage return) holds every
    one of ``needles``. Before it, stderr may hold only the log lines of stages that ended
    (``stage: 1.2 s``, what a progress bar writes where stderr is not a terminal).
    Returns the line."""
    err = proc.stderr
    assert proc.returncode == 2, (proc.returncode, err[-2000:])
    assert err.endswith("\n") and "Traceback" not in err, err[-2000:]
    *stages, line = err.rstrip("\n").split("\n")
    assert all(re.fullmatch(r"[^:]+: \d+\.\d s", s) for s in stages), err[-2000:]
    line = line.rsplit("\r", 1)[-1].strip()
    for needle in needles:
        assert needle in line, line
    return line


def hidden_files(folder: Path) -> list[str]:
    """Names of the dot files in ``folder`` (where temporaries would be left)."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def patch_tiff_size(path, width: int, height: int) -> None:
    """Set a little-endian TIFF's first image width and height tags (its strips unchanged)."""
    patch_tiff_tags(path, {256: width, 257: height})


def patch_tiff_tags(path, values: dict[int, int]) -> None:
    """Set integer tags of a little-endian TIFF's first image (its data unchanged)."""
    data = bytearray(path.read_bytes())
    ifd = struct.unpack_from("<I", data, 4)[0]
    for e in range(struct.unpack_from("<H", data, ifd)[0]):
        at = ifd + 2 + 12 * e
        tag, kind = struct.unpack_from("<HH", data, at)
        if tag in values:
            struct.pack_into("<I" if kind == 4 else "<H", data, at + 8, values[tag])
    path.write_bytes(bytes(data))
