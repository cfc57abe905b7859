"""Fuzzing the packed-layer readers under a memory bound, with a hang guard (issue 16).

Every case (a truncated, flipped, stretched or forged file) is parsed in a
worker process whose address space may grow by at most :data:`MEMORY_CAP`
over its warmed-up size (``resource.setrlimit(RLIMIT_AS)``); each case must
end in a layer or in the library's own error. A crash, a MemoryError, any
other exception or a hang (no answer in :data:`HANG` seconds) fails the test.
No wall-clock bound: the suite runs beside others in CI.
The long campaigns are ``@pytest.mark.slow``.
"""

from __future__ import annotations

import json
import select
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from terratheme.core.packing import PackedLayer, pack

MEMORY_CAP = 256 << 20
#: Seconds the parent waits for one answer before calling the worker hung.
HANG = 20.0

WORKER = r"""
import json, resource, struct, sys, time
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.packing import PackedLayer, TiledLayer, pack

# Warm every kernel a load can reach (compiled code is loaded once per process).
for fmt in ("seed", "streams", "plane"):
    for img in (np.arange(64, dtype=np.uint8).reshape(8, 8) % 3, np.zeros((40, 30), np.uint8)):
        layer = PackedLayer.from_bytes(pack(img).to_bytes(format=fmt))
        layer.lookup(1, 1); layer.lookup(np.arange(3), np.arange(3)); layer.unpack()
        tiled = TiledLayer.from_bytes(pack(img, tile_bits=6).to_bytes(format=fmt))
        tiled.lookup(np.arange(3), np.arange(3)); tiled.unpack()
def vm():
    for line in open("/proc/self/status"):
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
cap = vm() + int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
out = sys.stdout
out.write("ready\n"); out.flush()
stdin = sys.stdin.buffer
while True:
    head = stdin.read(4)
    if len(head) < 4:
        break
    data = stdin.read(struct.unpack("<I", head)[0])
    t = time.perf_counter()
    try:
        kind = TiledLayer if data[:4] == b"TTPT" else PackedLayer
        layer = kind.from_bytes(data)
        layer.lookup(np.zeros(1, np.int64), np.zeros(1, np.int64))
        outcome = "layer"
    except TerrathemeError:
        outcome = "error"
    except MemoryError:
        outcome = "MemoryError"
    except BaseException as exc:  # noqa: BLE001 - reported to the parent
        outcome = "crash: " + repr(exc)[:200]
    out.write(json.dumps({"outcome": outcome, "seconds": time.perf_counter() - t}) + "\n")
    out.flush()
"""


class Worker:
    """The bounded parser process: :meth:`parse` sends one file, returns its outcome."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", WORKER, str(MEMORY_CAP)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        assert self._line(300.0) == "ready"

    def _line(self, timeout: float) -> str:
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if not ready:
            self.proc.kill()
            raise AssertionError(f"worker hung for {timeout} s")
        line = self.proc.stdout.readline().decode().strip()
        if not line:
            raise AssertionError(f"worker died (exit {self.proc.wait()})")
        return line

    def parse(self, data: bytes) -> dict:
        self.proc.stdin.write(struct.pack("<I", len(data)) + data)
        self.proc.stdin.flush()
        return json.loads(self._line(HANG))

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=30)


@pytest.fixture(scope="module")
def worker():
    w = Worker()
    yield w
    w.close()


def _check(worker: Worker, data: bytes) -> str:
    res = worker.parse(data)
    assert res["outcome"] in ("layer", "error"), res
    return res["outcome"]


def _refresh(body: bytes | bytearray) -> bytes:
    """A file body with its payload size and CRC made consistent (so decoders see it)."""
    body = bytearray(body)
    if body[:4] == b"TTPT":
        return _refresh_container(body)
    if len(body) >= 36:
        struct.pack_into("<Q", body, 28, max(0, len(body) - 36 - _palette_bytes(body)))
    return bytes(body) + struct.pack("<I", zlib.crc32(body))


def _refresh_container(data: bytearray) -> bytes:
    """A tiled container with its header-and-index checksum made right (where it can be)."""
    if len(data) < 36:
        return bytes(data)
    flags, channels, sample, k = data[5], data[6], data[7], struct.unpack_from("<H", data, 8)[0]
    tiles = struct.unpack_from("<I", data, 20)[0] * struct.unpack_from("<I", data, 24)[0]
    pal = (0 if flags & 2 else k * channels * sample) + (k * (4 if flags & 8 else 3)
                                                         if flags & 4 else 0)
    at = 36 + pal + 16 * tiles
    if at + 4 <= len(data):
        struct.pack_into("<I", data, at, zlib.crc32(data[:at]))
    return bytes(data)


def _palette_bytes(body: bytes) -> int:
    flags, channels, sample, k = body[7], body[8], body[9], struct.unpack_from("<H", body, 10)[0]
    pal = 0 if flags & 2 else k * channels * sample
    return pal + (k * (4 if flags & 8 else 3) if flags & 4 else 0)


def _samples() -> list[bytes]:
    """Small valid files of every kind the writer makes."""
    rng = np.random.default_rng(3)
    blocks = np.kron(rng.integers(0, 4, (6, 5)), np.ones((4, 4), int)).astype(np.uint8)
    noise = rng.integers(0, 3, (9, 13)).astype(np.uint8)
    colour = np.stack([blocks * 40, 255 - blocks * 30, blocks], axis=2).astype(np.uint8)
    files = [pack(img).to_bytes(format=fmt) for img in (blocks, noise, colour)
             for fmt in ("seed", "streams", "plane")]
    files.append(pack(blocks, colours=np.array([[9, 9, 9], [200, 0, 0], [0, 200, 0],
                                                [0, 0, 200]], np.uint8)).to_bytes())
    wide = np.kron(rng.integers(0, 3, (3, 30)), np.ones((4, 4), int)).astype(np.uint8)
    files += [pack(img, tile_bits=6).to_bytes(format=fmt) for img in (wide, colour[:, :, :3])
              for fmt in ("seed", "compact")]
    # A big plane layer whose payload is a few bytes: forged streams must end fast too.
    files.append(PackedLayer.from_runs(4096, 4096, "hilbert", [4096 * 4096 - 1], [1],
                                       np.arange(2, dtype=np.uint8), identity=True,
                                       squeeze=True).to_bytes(format="plane"))
    return files


SAMPLES = _samples()


def test_samples_load(worker):
    assert all(_check(worker, data) == "layer" for data in SAMPLES)


def test_truncation_at_every_length(worker):
    for data in SAMPLES:
        for cut in range(len(data)):
            assert _check(worker, data[:cut]) == "error"


def test_truncation_with_consistent_header_and_checksum(worker):
    # The decoders, not the length check, must notice the missing payload bytes.
    for data in SAMPLES:
        for cut in range(40, len(data) - 4):
            _check(worker, _refresh(data[:cut]))


fuzz = settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
fuzz_long = settings(max_examples=3000, deadline=None, suppress_health_check=list(HealthCheck))


def _flip(data: bytes, where: int, bit: int, fix: bool) -> bytes:
    if data[:4] == b"TTPT":
        body = bytearray(data)
        body[where % len(body)] ^= 1 << bit
        return _refresh_container(body) if fix else bytes(body)
    body = bytearray(data[:-4])
    body[where % len(body)] ^= 1 << bit
    return _refresh(body) if fix else bytes(body) + data[-4:]


def _insert(data: bytes, where: int, extra: bytes) -> bytes:
    if data[:4] == b"TTPT":
        where = where % len(data)
        return _refresh_container(bytearray(data[:where] + extra + data[where:]))
    body = data[:-4]
    where = 36 + where % max(1, len(body) - 36)
    return _refresh(body[:where] + extra + body[where:])


def _forge(data: bytes, fields: dict) -> bytes:
    if data[:4] == b"TTPT":
        # Container fields: size, tile side, grid, palette size.
        body = bytearray(data)
        for offset, fmt, value in fields.values():
            offset = {4: 4, 5: 10, 7: 5, 8: 6, 10: 8, 12: 12, 16: 16, 20: 20}[offset]
            struct.pack_into(fmt, body, offset, value % (1 << (8 * struct.calcsize(fmt))))
        return _refresh_container(body)
    body = bytearray(data[:-4])
    for offset, fmt, value in fields.values():
        struct.pack_into(fmt, body, offset, value)
    return bytes(body) + struct.pack("<I", zlib.crc32(body))


HEADER_FIELDS = st.fixed_dictionaries({}, optional={
    "version": st.tuples(st.just(4), st.just("<B"), st.integers(0, 3)),
    "encoding": st.tuples(st.just(5), st.just("<B"), st.integers(0, 3)),
    "flags": st.tuples(st.just(7), st.just("<B"), st.integers(0, 255)),
    "channels": st.tuples(st.just(8), st.just("<B"), st.integers(0, 5)),
    "k": st.tuples(st.just(10), st.just("<H"), st.integers(0, 300)),
    "width": st.tuples(st.just(12), st.just("<I"), st.sampled_from([1, 7, 4096, 65535, 65536,
                                                                    65537, 2**32 - 1])),
    "height": st.tuples(st.just(16), st.just("<I"), st.sampled_from([1, 9, 4096, 65536])),
    "runs": st.tuples(st.just(20), st.just("<Q"), st.sampled_from(
        [0, 1, 2, 100, 1 << 20, (1 << 20) + 1, 1 << 30, 1 << 32, 2**64 - 1])),
})


def _cases(strategy):
    return st.tuples(st.sampled_from(SAMPLES), strategy)


@fuzz
@given(_cases(st.tuples(st.integers(0, 10**6), st.integers(0, 7), st.booleans())))
def test_bit_flips(worker, case):
    data, (where, bit, fix) = case
    _check(worker, _flip(data, where, bit, fix))


@fuzz
@given(_cases(st.tuples(st.integers(0, 10**6), st.binary(min_size=1, max_size=40))))
def test_insertions(worker, case):
    data, (where, extra) = case
    _check(worker, _insert(data, where, extra))


@fuzz
@given(_cases(HEADER_FIELDS))
def test_hostile_header_sizes(worker, case):
    data, fields = case
    _check(worker, _forge(data, fields))


@pytest.mark.slow
@fuzz_long
@given(_cases(st.tuples(st.integers(0, 10**6), st.integers(0, 7), st.booleans())))
def test_bit_flips_long(worker, case):
    data, (where, bit, fix) = case
    _check(worker, _flip(data, where, bit, fix))


@pytest.mark.slow
@fuzz_long
@given(_cases(st.tuples(st.integers(0, 10**6), st.binary(min_size=1, max_size=200))))
def test_insertions_long(worker, case):
    data, (where, extra) = case
    _check(worker, _insert(data, where, extra))


@pytest.mark.slow
@fuzz_long
@given(_cases(st.tuples(HEADER_FIELDS, st.integers(0, 10**6), st.integers(0, 7))))
def test_forged_headers_with_flips_long(worker, case):
    data, (fields, where, bit) = case
    _check(worker, _flip(_forge(data, fields), where, bit, True))
