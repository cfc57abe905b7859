"""A reader run on a hostile file in a worker process held to a time and memory bound.

The fuzz tests (``test_hostile_*.py``) hand each mutated file to
:class:`BoundedReader`, which runs one of the library's readers on it in a
long-lived worker process (started once, warmed up, so each case costs
milliseconds). The worker's address space is capped with
``resource.setrlimit(RLIMIT_AS)`` at its warmed-up size plus ``memory_mib``
(256 MiB), so a reader that allocates more than that fails with MemoryError;
each case's CPU time is measured (the bound: 2 s) and a case still running
after ``hang_seconds`` of wall time kills the worker. A case passes when the
reader succeeds or raises the library's own error with one line naming the
file; anything else (another exception, MemoryError, a crash, a hang, over
the time bound) fails it.

This file is also the worker's program (``python tests/test_hostile_harness.py
--worker``); its tests check that the bound catches what it should.
"""

from __future__ import annotations

import json
import os
import select
import struct
import subprocess
import sys
import time
import zlib
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: the bounds every hostile file must meet
MEMORY_MIB = 256
CPU_SECONDS = 2.0
#: the ``layer`` reader unpacks layers up to this size (a tiny file may rightly hold more)
MAX_UNPACKED_TEXELS = 1 << 22


@dataclass(frozen=True)
class Outcome:
    """What one case did: ``kind`` is ok, error (the library's), other, crash or hang."""

    kind: str
    seconds: float = 0.0
    error: str = ""
    message: str = ""

    @property
    def bounded(self) -> bool:
        return self.kind in ("ok", "error") and self.seconds <= CPU_SECONDS


class BoundedReader:
    """A worker process that runs readers on files within the memory bound."""

    def __init__(self, memory_mib: int = MEMORY_MIB, hang_seconds: float = 20.0) -> None:
        self.memory_mib = memory_mib
        self.hang_seconds = hang_seconds
        self.proc: subprocess.Popen | None = None

    def _start(self) -> None:
        env = dict(os.environ, MALLOC_ARENA_MAX="2", NUMBA_NUM_THREADS="1",
                   OMP_NUM_THREADS="1", PYTHONPATH=str(REPO))
        self.proc = subprocess.Popen(
            [sys.executable, __file__, "--worker", str(self.memory_mib)], cwd=REPO, env=env,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        ready = self._reply(120.0)
        if ready is None or ready.get("ready") is not True:
            err = self.proc.stderr.read().decode(errors="replace") if self.proc else ""
            raise RuntimeError(f"hostile-file worker did not start: {ready} {err[-2000:]}")

    def _reply(self, timeout: float) -> dict | None:
        assert self.proc is not None and self.proc.stdout is not None
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if not ready:
            return None
        line = self.proc.stdout.readline()
        if not line:
            self.proc.wait(10)
            return {"kind": "crash", "error": f"worker died, status {self.proc.returncode}"}
        return json.loads(line)

    def run(self, reader: str, path: Path) -> Outcome:
        """Run ``reader`` (a name in the worker's READERS) on the file at ``path``."""
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        assert self.proc is not None and self.proc.stdin is not None
        self.proc.stdin.write((json.dumps({"reader": reader, "path": str(path)}) + "\n").encode())
        self.proc.stdin.flush()
        reply = self._reply(self.hang_seconds)
        if reply is None:
            self.close()
            return Outcome("hang", error=f"no answer in {self.hang_seconds} s")
        return Outcome(**reply)

    def close(self) -> None:
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait()
            for stream in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
                if stream is not None:
                    stream.close()


_SHARED: list[BoundedReader] = []


def shared_reader() -> BoundedReader:
    """One worker for every hostile-file test module of a run (its start costs seconds)."""
    if not _SHARED:
        import atexit

        _SHARED.append(BoundedReader())
        atexit.register(_SHARED[0].close)
    return _SHARED[0]


def check_bounded(outcome: Outcome, path: Path) -> None:
    """Assert a case met the bounds and ended in success or one line naming the file."""
    assert outcome.bounded, f"{path.name}: {outcome}"
    if outcome.kind == "error":
        assert "\n" not in outcome.message, outcome.message
        assert path.name in outcome.message, outcome.message


# -- hostile ZIP archives ----------------------------------------------------

@dataclass(frozen=True)
class ZipMember:
    """One member of a crafted ZIP: its stored bytes and what its headers claim."""

    name: str
    stored: bytes
    file_size: int
    crc: int
    method: int = 8
    flags: int = 0

    @classmethod
    def of(cls, name: str, data: bytes, method: int = 8) -> ZipMember:
        """An honest member: ``data`` deflated (method 8) or stored (method 0)."""
        if method == 8:
            co = zlib.compressobj(6, zlib.DEFLATED, -15)
            stored = co.compress(data) + co.flush()
        else:
            stored = data
        return cls(name, stored, len(data), zlib.crc32(data), method)


def craft_zip(members: list[ZipMember]) -> bytes:
    """A ZIP archive whose headers say exactly what the members claim (APPNOTE 4.3)."""
    body, central = bytearray(), bytearray()
    for m in members:
        name = m.name.encode()
        offset = len(body)
        body += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, m.flags, m.method, 0, 0, m.crc,
                            len(m.stored), m.file_size & 0xFFFFFFFF, len(name), 0)
        body += name + m.stored
        central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, m.flags, m.method, 0,
                               0, m.crc, len(m.stored), m.file_size & 0xFFFFFFFF, len(name), 0,
                               0, 0, 0, 0, offset)
        central += name
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(members), len(members), len(central),
                      len(body), 0)
    return bytes(body + central + end)


def npy_bytes(header: str, body: bytes = b"") -> bytes:
    """An ``.npy`` file (version 1.0) with the header dict text given verbatim."""
    text = header.encode("latin-1")
    pad = (-(10 + len(text) + 1)) % 64
    text += b" " * pad + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text + body


# -- the worker -------------------------------------------------------------

def _vm_bytes() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


def _readers() -> dict:
    import numpy as np
    from terratheme.core.classify import Classifier
    from terratheme.core.classify.photo import prepare_photo
    from terratheme.core.classify.shipped import load_model, shipped_models
    from terratheme.core.classify.training_cache import cached_samples
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.exchange.maps_to_grid import grid_from_maps
    from terratheme.core.io.disk_cache import DiskCache
    from terratheme.core.io.georef import read_georeference
    from terratheme.core.io.images import Bands, image_info, read_image, read_labels, read_region
    from terratheme.core.model.project import load_project
    from terratheme.core.packing import layer_info, load_layer

    photo = np.zeros((48, 48, 3), np.uint8)
    photo[:, 24:] = (200, 180, 120)

    def model(path):
        # A model that loads must also predict: a bad feature index would crash here.
        Classifier.load(path).predict(photo)

    def image(path):
        info = image_info(path)
        read_image(path)
        read_region(path, 0, 0, min(info.width, 3), min(info.height, 3))

    def as_photo(path):
        prepare_photo(read_image(path, bands=Bands.PHOTO))

    def layer(path):
        # What info, unpack and lookups do: the header, then every band of a small layer.
        layer_info(path)
        packed = load_layer(path)
        packed.lookup(np.zeros(1, np.int64), np.zeros(1, np.int64))
        if packed.width * packed.height <= MAX_UNPACKED_TEXELS:
            for _ in packed.bands():
                pass

    def engine_map(kind: str, n_themes: int, copies: int = 1):
        # new --from KIND: headers, then every band; a second copy compares their headers.
        return lambda path: grid_from_maps([str(path)] * copies, kind, n_themes, 1)

    def cache(path):
        # A hostile cache entry is a miss (computed again), or whole finite samples.
        key, kind = path.name.split(".")
        x, y = cached_samples(DiskCache(path.parent), key, 6, (1, 2), lambda: (
            np.zeros((0, 6), np.float32), np.zeros(0, np.uint8)))
        if not (np.isfinite(x).all() and x.shape[1] == 6 and y.shape == (len(x),)):
            raise AssertionError("a cache entry's samples were not checked")

    def index(path):
        # models.json: the index, then every model it lists (sizes and digests checked).
        for name in shipped_models(path.parent):
            try:
                load_model(name, path.parent)
            except TerrathemeError:
                pass

    def allocate(path):
        # For the harness's own test: asks for 1 GiB.
        np.ones(1 << 30, np.uint8)

    def spin(path):
        end = time.process_time() + CPU_SECONDS + 0.2
        while time.process_time() < end:
            pass

    def crash(path):
        os.abort()

    return {"project": load_project, "model": model, "image": image, "labels": read_labels,
            "georef": read_georeference, "photo": as_photo, "layer": layer, "cache": cache,
            "index": index, "allocate": allocate, "spin": spin, "crash": crash,
            "splatmap": engine_map("splatmap", 4), "weights": engine_map("weights", 2, 2),
            "control": engine_map("terrain3d", 32)}


def _warm_up(readers: dict) -> None:
    """Run every real reader once on a good file, so imports and caches are in place."""
    import tempfile

    import numpy as np
    from terratheme.core.classify import SupervisedOptions
    from terratheme.core.classify.extra_trees import ExtraTreesForest
    from terratheme.core.classify.model_file import ModelParts, write_model
    from terratheme.core.exchange.terrain3d import write_control_map
    from terratheme.core.io.disk_cache import DiskCache
    from terratheme.core.io.images import write_image
    from terratheme.core.model.grid import IndexGrid
    from terratheme.core.model.project import ThematicTexture, save_project
    from terratheme.core.packing import pack
    from terratheme.core.themes.library import ThemeLibrary, flat_theme

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        img = np.zeros((32, 32, 3), np.uint8)
        img[:, 16:] = 200
        mask = np.zeros((32, 32), np.uint8)
        mask[8, 2:12], mask[8, 20:30] = 1, 2
        # A stump on lightness, made by hand (training would import scikit-learn: seconds).
        stump = ExtraTreesForest.from_arrays({
            "classes": np.array([1, 2]), "roots": np.array([0]), "feature": np.array([0, -1, -1]),
            "threshold": np.array([50.0, 0, 0]), "left": np.array([1, -1, -1]),
            "right": np.array([2, -1, -1]), "value": np.array([[0, 0], [1, 0], [0, 1.0]])})
        write_model(d / "m.ttc", ModelParts(stump, (1, 2), SupervisedOptions(), None))
        readers["model"](d / "m.ttc")
        save_project(d / "p.ttproj", ThematicTexture(
            IndexGrid(np.zeros((2, 2), np.uint8), (4, 4)),
            ThemeLibrary([flat_theme("a", (1, 2, 3))])))
        readers["project"](d / "p.ttproj")
        for suffix in (".png", ".jpg", ".tif"):
            write_image(d / f"i{suffix}", img)
            readers["image"](d / f"i{suffix}")
            readers["photo"](d / f"i{suffix}")
            readers["georef"](d / f"i{suffix}")
        write_image(d / "l.png", mask, palette=np.zeros((3, 3), np.uint8) + [[0], [1], [2]])
        readers["labels"](d / "l.png")
        write_image(d / "s.png", np.zeros((5, 5, 4), np.uint8))
        readers["splatmap"](d / "s.png")
        readers["weights"](d / "l.png")
        write_control_map(d / "c.exr", np.zeros((5, 5), np.uint32))
        readers["control"](d / "c.exr")
        # Every payload kind and the tiled container load their own kernels.
        for i, (fmt, tile_bits) in enumerate([("seed", None), ("streams", None),
                                              ("plane", None), ("compact", 6)]):
            pack(mask, tile_bits=tile_bits).save(d / f"{i}.ttpack", format=fmt)
            readers["layer"](d / f"{i}.ttpack")
        # A container of several tiles looks up through its joined table (kernels of its own).
        pack(np.tile(mask, (5, 5)), tile_bits=6).save(d / "tiles.ttpack")
        readers["layer"](d / "tiles.ttpack")
        DiskCache(d).store("0" * 64, "samples", {"features": np.ones((2, 6), np.float32),
                                                 "labels": np.array([1, 2], np.uint8)})
        readers["cache"](d / f"{'0' * 64}.samples")
        (d / "models.json").write_text(json.dumps({"models": {"m": {
            "file": "m.ttc", "classes": {"1": "a", "2": "b"}}}}))
        readers["index"](d / "models.json")


def _worker(memory_mib: int) -> None:
    import resource

    import OpenImageIO as oiio
    from terratheme.core.errors import TerrathemeError

    oiio.attribute("threads", 1)
    readers = _readers()
    _warm_up(readers)
    limit = _vm_bytes() + (memory_mib << 20)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    out = sys.stdout
    out.write(json.dumps({"ready": True}) + "\n")
    out.flush()
    for line in sys.stdin:
        request = json.loads(line)
        start = time.process_time()
        try:
            readers[request["reader"]](Path(request["path"]))
            reply = {"kind": "ok"}
        except TerrathemeError as exc:
            reply = {"kind": "error", "error": type(exc).__name__, "message": str(exc)}
        except BaseException as exc:  # the harness reports everything else
            reply = {"kind": "other", "error": type(exc).__name__, "message": str(exc)[:500]}
        reply["seconds"] = time.process_time() - start
        out.write(json.dumps(reply) + "\n")
        out.flush()


if __name__ == "__main__" and sys.argv[1:2] == ["--worker"]:
    sys.path.insert(0, str(REPO))
    _worker(int(sys.argv[2]))


# -- the harness's own tests ---------------------------------------------------

@pytest.fixture(scope="module")
def worker():
    return shared_reader()


def test_a_reader_that_allocates_too_much_fails_the_bound(worker, tmp_path):
    outcome = worker.run("allocate", tmp_path / "x")
    assert outcome.kind == "other" and "MemoryError" in outcome.error
    assert not outcome.bounded


@pytest.mark.slow
def test_a_reader_that_spins_fails_the_bound(worker, tmp_path):
    outcome = worker.run("spin", tmp_path / "x")
    assert outcome.kind == "ok" and outcome.seconds > CPU_SECONDS and not outcome.bounded


def test_a_crash_fails_the_bound_and_the_next_case_runs(worker, tmp_path):
    assert worker.run("crash", tmp_path / "x").kind == "crash"
    outcome = worker.run("project", tmp_path / "missing.ttproj")
    assert outcome.kind == "error" and "no such project" in outcome.message
    check_bounded(outcome, tmp_path / "missing.ttproj")
