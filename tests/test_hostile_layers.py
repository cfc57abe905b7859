"""Hostile packed layers from a file: the plane payload (version 2) and the tiled container.

``tests/test_packing_fuzz.py`` parses hostile bytes in memory; this campaign
takes the path a user's file takes: :func:`core.packing.load_layer` on a
file (the tiled container reads its tiles lazily, so damage in a late tile
shows only while unpacking), :func:`core.packing.layer_info`, every band of
a streamed unpack, and the real ``unpack`` and ``info`` commands: status 2,
one line, no output file and no temporary left behind.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from hostile_fuzz import (
    EDITS,
    campaign,
    check_refused,
    hidden_files,
    run_bytes,
    run_cli,
    run_edited,
    run_truncations,
)
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError, UnsupportedVersionError
from terratheme.core.packing import layer_info, load_layer, pack, write_layer_image
from test_hostile_harness import shared_reader


def _image() -> np.ndarray:
    rng = np.random.default_rng(5)
    return np.kron(rng.integers(0, 4, (9, 25)), np.ones((8, 8), int)).astype(np.uint8)


@pytest.fixture(scope="module")
def samples(tmp_path_factory) -> dict[str, bytes]:
    """Small valid files: the plane payload and a tiled container of 4 x 2 tiles."""
    folder = tmp_path_factory.mktemp("layers")
    out = {}
    for name, fmt, tile_bits in [("plane", "plane", None), ("streams", "streams", None),
                                 ("tiled", "compact", 6), ("tiled_seed", "seed", 6)]:
        path = folder / f"{name}.ttpack"
        pack(_image(), tile_bits=tile_bits).save(path, format=fmt)
        out[name] = path.read_bytes()
    assert out["tiled"][:4] == b"TTPT" and len(out["tiled"]) < 4000
    return out


@pytest.fixture(scope="module")
def bounded():
    return shared_reader()


NAMES = ["plane", "streams", "tiled", "tiled_seed"]


@campaign
@pytest.mark.parametrize("name", NAMES)
def test_truncations_of_a_layer_file(budget, bounded, samples, tmp_path, name):
    kinds = run_truncations(bounded, "layer", samples[name], tmp_path / "cut.ttpack", budget)
    assert kinds == {"error"}


@campaign
def test_flips_and_insertions(budget, bounded, samples, tmp_path):
    budget.explore(lambda name, edits: run_edited(bounded, "layer", samples[name],
                                                  tmp_path / "mut.ttpack", edits),
                   name=st.sampled_from(NAMES), edits=EDITS)


def _with_checksum(body: bytes) -> bytes:
    """A single-layer file's body with its CRC-32 recomputed (so the decoders see the edit)."""
    return body + struct.pack("<I", zlib.crc32(body))


#: header fields a forger may set (offset, struct format, values): the payload size is
#: left alone, so a file stays as long as it says it is
HEADER_FIELDS = st.sampled_from([
    (5, "<B", st.integers(0, 3)), (6, "<B", st.integers(0, 2)), (7, "<B", st.integers(0, 255)),
    (8, "<B", st.integers(0, 5)), (10, "<H", st.integers(0, 300)),
    (12, "<I", st.sampled_from([1, 199, 200, 201, 4096, 65536, 2**32 - 1])),
    (16, "<I", st.sampled_from([1, 71, 72, 73, 4096, 65536])),
    (20, "<Q", st.sampled_from([0, 1, 2, 100, 1 << 20, 1 << 32, 2**64 - 1]))])


def _forged(data: bytes, fields: list, flips: list[tuple[int, int]]) -> bytes:
    body = bytearray(data[:-4])
    for (offset, fmt, _), value in fields:
        struct.pack_into(fmt, body, offset, value)
    for where, mask in flips:
        body[36 + where % (len(body) - 36)] ^= mask or 0xFF
    return _with_checksum(bytes(body))


@campaign
def test_consistent_flips_and_forged_headers_reach_the_decoders(budget, bounded, samples,
                                                                 tmp_path):
    # With the checksum made right, the payload decoders (plane, streams) see every edit.
    fields = HEADER_FIELDS.flatmap(lambda f: st.tuples(st.just(f), f[2]))
    budget.explore(lambda name, forged, flips: run_bytes(
        bounded, "layer", tmp_path / "forged.ttpack", _forged(samples[name], forged, flips)),
        name=st.sampled_from(["plane", "streams"]), forged=st.lists(fields, max_size=2),
        flips=st.lists(st.tuples(st.integers(0, 1 << 16), st.integers(0, 255)), max_size=4))


def _damaged_last_tile(data: bytes) -> bytes:
    """The tiled sample with one byte of its last tile flipped (the index left intact)."""
    out = bytearray(data)
    out[-10] ^= 0x40
    return bytes(out)


def test_a_damaged_late_tile_is_found_while_unpacking_and_leaves_no_file(samples, tmp_path):
    path = tmp_path / "late.ttpack"
    path.write_bytes(_damaged_last_tile(samples["tiled"]))
    layer = load_layer(path)  # the header and index are sound: tiles are read on demand
    with pytest.raises(TerrathemeError, match="late.ttpack") as exc:
        write_layer_image(layer, tmp_path / "out.png")
    assert "\n" not in str(exc.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["late.ttpack"]


@pytest.mark.parametrize("name", ["plane", "tiled"])
def test_a_newer_version_is_named_as_such(samples, tmp_path, name):
    data = bytearray(samples[name])
    data[4] += 1  # the format version byte of both layouts
    path = tmp_path / "new.ttpack"
    path.write_bytes(bytes(data))
    with pytest.raises(UnsupportedVersionError, match="new.ttpack"):
        load_layer(path)
    with pytest.raises(UnsupportedVersionError, match="new.ttpack"):
        layer_info(path)


def test_a_declared_size_far_beyond_the_bytes_is_refused(samples, tmp_path):
    data = bytearray(samples["tiled"])
    struct.pack_into("<II", data, 12, 1 << 30, 1 << 30)  # width, height of the container
    path = tmp_path / "huge.ttpack"
    path.write_bytes(bytes(data))
    with pytest.raises(TerrathemeError, match="huge.ttpack"):
        load_layer(path).unpack()


# -- the real command line --------------------------------------------------

def _cases(samples) -> dict[str, bytes]:
    return {"truncated.ttpack": samples["plane"][:40],
            "flipped.ttpack": samples["plane"][:30] + bytes([samples["plane"][30] ^ 1])
            + samples["plane"][31:],
            "late.ttpack": _damaged_last_tile(samples["tiled"]),
            "empty.ttpack": b"", "notalayer.ttpack": b"PK\x03\x04" + bytes(60)}


SLOW = pytest.mark.slow
#: the pairs the quick suite runs; -m slow runs every hostile file into both outputs
QUICK_UNPACKS = {("late.ttpack", "out.tif"), ("truncated.ttpack", "out.png"),
                 ("notalayer.ttpack", "out.png")}
UNPACK_CASES = [pytest.param(case, out, marks=() if (case, out) in QUICK_UNPACKS else SLOW)
                for case in ["truncated.ttpack", "flipped.ttpack", "late.ttpack", "empty.ttpack",
                             "notalayer.ttpack"] for out in ["out.png", "out.tif"]]


@pytest.mark.parametrize(("case", "out"), UNPACK_CASES)
def test_unpack_of_a_hostile_layer_is_one_line_and_leaves_nothing(samples, tmp_path, case,
                                                                   out):
    (tmp_path / case).write_bytes(_cases(samples)[case])
    check_refused(run_cli("unpack", tmp_path / case, tmp_path / out), case)
    assert sorted(p.name for p in tmp_path.iterdir()) == [case] and not hidden_files(tmp_path)


@pytest.mark.parametrize("case", ["truncated.ttpack", pytest.param("empty.ttpack", marks=SLOW),
                                  pytest.param("notalayer.ttpack", marks=SLOW)])
def test_info_of_a_hostile_layer_is_one_line(samples, tmp_path, case):
    (tmp_path / case).write_bytes(_cases(samples)[case])
    check_refused(run_cli("info", tmp_path / case), case)


# -- streamed unpack of tiled containers into tiled images ----------------------

@pytest.mark.parametrize("out", ["back.tif", "back.png"])
def test_a_tiled_container_unpacks_to_every_format(samples, tmp_path, out):
    # Found by this campaign: the container's 64-row bands did not fit the TIFF's 256-row
    # tiles, and unpack to .tif failed with an empty "cannot write out.tif:" line.
    from terratheme.core.io.images import read_labels

    (tmp_path / "t.ttpack").write_bytes(samples["tiled"])
    write_layer_image(load_layer(tmp_path / "t.ttpack"), tmp_path / out)
    np.testing.assert_array_equal(read_labels(tmp_path / out), _image())


def test_the_tiled_writer_gathers_bands_of_any_height(tmp_path):
    from terratheme.core.io import TiledImageWriter
    from terratheme.core.io.images import read_image

    image = np.arange(70 * 40, dtype=np.uint16).reshape(70, 40) % 997
    with TiledImageWriter(tmp_path / "b.tif", 40, 70, 1, np.uint16, tile=32) as out:
        for y, h in [(0, 5), (5, 30), (35, 1), (36, 34)]:
            out.write(0, y, image[y:y + h])
    np.testing.assert_array_equal(read_image(tmp_path / "b.tif").reshape(70, 40), image)
    with pytest.raises(TerrathemeError, match="bands must come in order from the top: row 9 "
                                              "after row 4"), \
            TiledImageWriter(tmp_path / "c.tif", 40, 70, 1, np.uint16, tile=32) as out:
        out.write(0, 0, image[:5])
        out.write(0, 9, image[9:12])
    with pytest.raises(TerrathemeError, match="rows from 32 on were never written"), \
            TiledImageWriter(tmp_path / "d.tif", 40, 70, 1, np.uint16, tile=32) as out:
        out.write(0, 0, image[:40])
    with pytest.raises(TerrathemeError, match=r"region at \(0, 0\) of 20 x 5 pixels is not on "
                                              r"the 32-pixel tile grid"), \
            TiledImageWriter(tmp_path / "e.tif", 40, 70, 1, np.uint16, tile=32) as out:
        out.write(0, 0, image[:5, :20])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.tif"]
