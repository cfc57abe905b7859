"""Packed layers: the seed's worked example, round trips, big layers, palettes."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import sfc_steps
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.curves.scan import ranks_to_steps
from terratheme.core.errors import TerrathemeError
from terratheme.core.packing import PackedLayer, pack
from terratheme.core.packing.seed_format import (
    decode_varint_stream,
    encode_seed_runs,
    encode_varints,
)


@pytest.fixture(scope="module")
def vec(shared_vectors):
    return json.loads((shared_vectors / "sfc_8x8.json").read_text())


@pytest.mark.parametrize("curve", ["hilbert", "morton"])
def test_runs_match_vector_file(vec, curve):
    layer = pack(np.array(vec["index_image"], dtype=np.uint8), curve)
    assert layer.S.tolist() == vec[f"{curve}_runs"]["S"]
    assert layer.P.tolist() == vec[f"{curve}_runs"]["P"]
    assert layer.run_count == len(vec[f"{curve}_runs"]["S"])
    assert layer.curve.name.lower() == curve


def test_varint_examples(vec):
    for value, expected in vec["varint_examples"]["values"].items():
        table, used = encode_varints(np.array([int(value)], np.uint64))
        assert list(table[used]) == expected
        assert decode_varint_stream(bytes(expected), 1, name="v").tolist() == [int(value)]


def test_seed_payload_of_table_3(vec):
    # 8 x 8 square: every step is a texel, so lengths are differences of the seed's S.
    s = vec["hilbert_runs"]["S"]
    lengths = np.diff([0, *s])
    # Every run here is shorter than 128: one varint byte, its high bit set (the last byte).
    expected = b"".join(bytes([int(n) | 0x80, p])
                        for n, p in zip(lengths, vec["hilbert_runs"]["P"], strict=True))
    layer = pack(np.array(vec["index_image"], dtype=np.uint8), "hilbert")
    data = layer.to_bytes(format="seed")
    assert expected in data
    assert len(expected) == 2 * len(s)  # every run here is shorter than 128
    assert encode_seed_runs(lengths, np.array(vec["hilbert_runs"]["P"], np.uint8)) == expected


def test_auto_keeps_the_curve_with_fewer_runs(vec):
    img = np.array(vec["index_image"], dtype=np.uint8)
    assert pack(img, "auto").curve.name == "HILBERT"  # 15 runs against Morton's 22
    # 8 x 8, top half 1, bottom half 0: Morton (BL, BR, TL, TR) gives 2 runs,
    # Hilbert (n = 3: BL, TL, TR, BR) 3.
    halves = np.repeat(np.array([[1], [0]], np.uint8), 4, axis=0).repeat(8, axis=1)
    assert pack(halves, "morton").run_count == 2
    assert pack(halves, "hilbert").run_count == 3
    assert pack(halves, "auto").curve.name == "MORTON"


def test_colour_image_palette_in_order_of_first_appearance(vec):
    idx = np.array(vec["index_image"], dtype=np.uint8)
    colours = np.array([[0, 0, 0], [250, 0, 0], [0, 250, 0], [0, 0, 250],
                        [9, 9, 9], [1, 2, 3], [7, 7, 200]], np.uint8)
    rgb = colours[idx]
    layer = pack(rgb, "hilbert")
    # Indices 1..6 first appear in that order along the curve (Table 3), so P = index - 1.
    assert layer.P.tolist() == [p - 1 for p in vec["hilbert_runs"]["P"]]
    assert np.array_equal(layer.palette, colours[1:7])
    assert np.array_equal(layer.unpack(), rgb)
    assert np.array_equal(layer.lookup(np.array([0, 7]), np.array([0, 7])), rgb[[0, 7], [0, 7]])


@st.composite
def images(draw):
    w = draw(st.sampled_from([1, 2, 3, 5, 8, 13, 33, 64, 70]))
    h = draw(st.sampled_from([1, 2, 4, 7, 16, 31, 65]))
    kind = draw(st.sampled_from(["index2d", "index3d", "rgb", "rgba", "u16"]))
    colours = draw(st.sampled_from([1, 2, 5, 40]))
    blocky = draw(st.booleans())
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if blocky:
        # Few long runs: a coarse random grid scaled up.
        coarse = rng.integers(0, colours, (max(1, h // 4), max(1, w // 4)))
        idx = np.kron(coarse, np.ones((4, 4), int))
        idx = np.pad(idx, ((0, max(0, h - idx.shape[0])), (0, max(0, w - idx.shape[1]))),
                     mode="edge")[:h, :w]
    else:
        idx = rng.integers(0, colours, (h, w))
    if kind == "index2d":
        return idx.astype(np.uint8)
    if kind == "index3d":
        return idx.astype(np.uint8)[:, :, None]
    if kind == "u16":
        return (idx * 1000 + 7).astype(np.uint16)
    table = rng.integers(0, 256, (colours, 3 if kind == "rgb" else 4)).astype(np.uint8)
    return table[idx]


@settings(max_examples=60, deadline=None)
@given(images(), st.sampled_from(["hilbert", "morton", "auto"]),
       st.sampled_from(["seed", "compact"]))
def test_round_trip_through_file(tmp_path_factory, image, curve, fmt):
    path = tmp_path_factory.mktemp("rt") / "layer.ttp"
    layer = pack(image, curve)
    size = layer.save(path, format=fmt)
    assert path.stat().st_size == size
    back = PackedLayer.load(path)
    assert np.array_equal(back.S, layer.S) and np.array_equal(back.P, layer.P)
    unpacked = back.unpack()
    assert unpacked.dtype == image.dtype and np.array_equal(unpacked, image)
    h, w = image.shape[:2]
    rows, cols = np.mgrid[0:h, 0:w]
    assert np.array_equal(back.lookup(cols, rows), image[rows, cols])
    assert np.array_equal(back.lookup(int(w - 1), 0), image[0, w - 1])
    # The in-memory structure stays under the seed's 5 bytes per run (plus a fixed header).
    assert back.memory_bytes <= 5 * back.run_count + 4 * (8 + 1040 + 2) + 4 * 4**3


def _quadrant_layer(curve: str) -> PackedLayer:
    # Four runs, one per quadrant of the 2^32-step square (2^30 texels each).
    steps = np.array([1, 2, 3, 4], np.int64) * 2**30 - 1
    return PackedLayer.from_runs(65536, 65536, curve, steps, np.arange(4),
                                 np.arange(4, dtype=np.uint8), squeeze=True)


@pytest.mark.parametrize("curve,expected", [
    # Hilbert, n = 16 (transposed so the first move is up): BL, BR, TR, TL.
    ("hilbert", {"bl": 0, "br": 1, "tr": 2, "tl": 3, "c": 1, "c1": 3}),
    # Morton: digit x + 2y -> BL, BR, TL, TR.
    ("morton", {"bl": 0, "br": 1, "tl": 2, "tr": 3, "c": 1, "c1": 2}),
])
def test_65536_square_from_runs(tmp_path, curve, expected):
    layer = _quadrant_layer(curve)
    points = {"bl": (0, 65535), "br": (65535, 65535), "tr": (65535, 0), "tl": (0, 0),
              "c": (32768, 32768), "c1": (32767, 32767)}
    xs = np.array([p[0] for p in points.values()])
    ys = np.array([p[1] for p in points.values()])
    want = [expected[k] for k in points]
    assert layer.lookup(xs, ys).tolist() == want
    assert [int(layer.lookup(int(x), int(y))) for x, y in zip(xs, ys, strict=True)] == want
    path = tmp_path / "big.ttp"
    layer.save(path, format="seed")
    back = PackedLayer.load(path)
    assert back.lookup(xs, ys).tolist() == want
    assert back.lengths.tolist() == [2**30] * 4


def test_one_run_covering_all_2_32_texels(tmp_path):
    layer = PackedLayer.from_runs(65536, 65536, "hilbert", [2**32 - 1], [0], [[9]])
    layer.save(tmp_path / "one.ttp", format="seed")
    back = PackedLayer.load(tmp_path / "one.ttp")
    assert back.lengths.tolist() == [2**32]
    assert back.lookup(np.array([0, 65535]), np.array([65535, 0])).tolist() == [[9], [9]]


def test_lookup_errors():
    layer = pack(np.zeros((4, 6), np.uint8))
    with pytest.raises(TerrathemeError, match=r"\(6, 0\) is outside the 6 x 4"):
        layer.lookup(6, 0)
    with pytest.raises(TerrathemeError, match="outside"):
        layer.lookup(np.array([0, 1]), np.array([0, -1]))
    with pytest.raises(TerrathemeError, match="outside"):
        layer.lookup(2**70, 0)
    with pytest.raises(TerrathemeError, match="outside"):
        layer.lookup(np.int64(-1), np.int64(0))
    with pytest.raises(TerrathemeError, match="integers"):
        layer.lookup(np.array([0.5]), np.array([0]))


def test_too_many_colours_refused_then_reduced():
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (40, 50, 3)).astype(np.uint8)
    with pytest.raises(TerrathemeError,
                       match=r"2\d\d\d colours, more than the 256.*palette \(reduce_palette\)$"):
        pack(img)
    layer = pack(img, reduce_palette=True)
    report = layer.report
    assert report.colours_before == np.unique(img.reshape(-1, 3), axis=0).shape[0]
    assert report.colours_after <= 256 and layer.palette.shape[0] <= 256
    reduced = layer.unpack()
    err = np.linalg.norm(reduced.astype(float) - img.astype(float), axis=2)
    assert report.max_error == pytest.approx(err.max(), abs=1e-6)
    assert report.mean_error == pytest.approx(err.mean(), abs=1e-6)
    assert 0 < report.mean_error <= report.max_error
    # Each texel takes its nearest palette entry.
    pal = layer.palette.reshape(-1, 3).astype(float)
    nearest = np.linalg.norm(img.astype(float)[:, :, None, :] - pal, axis=3).min(axis=2)
    assert np.allclose(err, nearest)


def test_a_reduced_palette_keeps_clustered_colours_within_their_cluster():
    # Three colours, each spread +-3 per channel: up to 3 x 343 distinct colours, more than
    # 256, but every texel lies within 6 sqrt(3) of any palette entry in its own cube.
    rng = np.random.default_rng(5)
    base = np.array([(40, 80, 200), (200, 190, 60), (120, 30, 90)])
    which = rng.integers(0, 3, (60, 60))
    img = (base[which] + rng.integers(-3, 4, (60, 60, 3))).astype(np.uint8)
    assert np.unique(img.reshape(-1, 3), axis=0).shape[0] > 256
    layer = pack(img, reduce_palette=True)
    reduced = layer.unpack().astype(float)
    assert np.abs(reduced - base[which]).max() <= 3
    assert layer.report.max_error <= 6 * np.sqrt(3)


def test_unsupported_inputs():
    with pytest.raises(TerrathemeError, match="0 x 0 texels"):
        pack(np.zeros((0, 0), np.uint8))
    with pytest.raises(TerrathemeError, match="float32"):
        pack(np.zeros((3, 3), np.float32))
    with pytest.raises(TerrathemeError, match="5 channels"):
        pack(np.zeros((3, 3, 5), np.uint8))
    with pytest.raises(TerrathemeError, match="unknown curve"):
        pack(np.zeros((3, 3), np.uint8), "peano")


def test_from_runs_validates():
    with pytest.raises(TerrathemeError, match="palette index 4 out of range"):
        PackedLayer.from_runs(2, 2, "hilbert", [3], [4], [[0], [1]])
    with pytest.raises(TerrathemeError, match="last run ends at step 2"):
        PackedLayer.from_runs(2, 2, "hilbert", [2], [0], [[0]])
    with pytest.raises(TerrathemeError, match="strictly increasing"):
        PackedLayer.from_runs(2, 2, "hilbert", [2, 1, 3], [0, 1, 0], [[0], [1]])
    # 3 x 2 image, Morton: step 5 is (x=3, y=0), outside the image.
    with pytest.raises(TerrathemeError, match="outside the image"):
        PackedLayer.from_runs(3, 2, "morton", [5, 6], [0, 1], [[0], [1]])


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 65536), st.integers(1, 65536), st.sampled_from(["hilbert", "morton"]),
       st.integers(1, 300), st.integers(0, 2**32 - 1))
def test_lookup_agrees_with_numpy_searchsorted(width, height, curve, runs, seed):
    # Random runs on a large layer (no dense image): the kernel against the seed's algorithm
    # written with numpy (step of each texel, then the first run with S >= step).
    rng = np.random.default_rng(seed)
    total = width * height
    ends = np.unique(np.append(rng.integers(1, total + 1, runs), total))
    steps = ranks_to_steps(ends, width, height, curve).astype(np.int64)
    indices = rng.integers(0, 7, ends.size)
    layer = PackedLayer.from_runs(width, height, curve, steps, indices, np.arange(7),
                                  squeeze=True)
    # Over 2^16 points: the multi-threaded kernel; the serial one below.
    xs = rng.integers(0, width, 70_000)
    ys = rng.integers(0, height, 70_000)
    s = sfc_steps.steps_of(xs, ys, width, height, curve).astype(np.int64)
    expected = indices[np.searchsorted(steps, s, side="left")]
    assert np.array_equal(layer.lookup(xs, ys), expected)
    assert np.array_equal(dataclasses.replace(layer, threads=1).lookup(xs, ys), expected)
    assert layer.lookup(int(xs[0]), int(ys[0])) == expected[0]
    # The runs come back from the random-access table alone.
    assert np.array_equal(layer.steps, steps) and np.array_equal(layer.P, indices)


def test_real_mask_round_trip(tmp_path, shared_data):
    from terratheme.core.io.images import read_image

    path = sorted((shared_data / "dubai" / "masks").glob("*.png"))[0]
    img = read_image(path)
    for curve in ("hilbert", "morton"):
        layer = pack(img, curve)
        for fmt in ("seed", "compact"):
            layer.save(tmp_path / "m.ttp", format=fmt)
            back = PackedLayer.load(tmp_path / "m.ttp")
            assert np.array_equal(back.unpack(), img)
            ys = np.random.default_rng(0).integers(0, img.shape[0], 5000)
            xs = np.random.default_rng(1).integers(0, img.shape[1], 5000)
            assert np.array_equal(back.lookup(xs, ys), img[ys, xs])
