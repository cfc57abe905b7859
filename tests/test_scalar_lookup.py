"""Scalar lookups (``layer.lookup(x, y)`` on Python ints) against the dense image (issue 19).

Every texel of random small maps, both curves, odd sizes, palettes of 1 to 256
entries (index 255 included: its uniform cells take the compiled call), every
layout the packer writes (the layer in memory, another grid, the file
encodings, tiled containers joined or not) and quick cells wider than 16.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.packing import PackedLayer, TiledLayer, pack, scalar

FORMATS = ("compact", "plane", "streams", "seed")


@st.composite
def index_maps(draw, most: int = 70) -> np.ndarray:
    """(H, W) uint8 maps: blocks of one index, some noise, values from a palette of 1..256."""
    w, h = draw(st.integers(1, most)), draw(st.integers(1, most))
    k = draw(st.sampled_from([1, 2, 3, 7, 16, 100, 256]))
    cell = draw(st.integers(1, 24))
    noise = draw(st.sampled_from([0.0, 0.03, 0.4]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    values = rng.permutation(256)[:k]
    if draw(st.booleans()):
        values[0] = 255  # cells of index 255 are marked 255 in the quick cells
    coarse = rng.integers(0, k, (-(-h // cell), -(-w // cell)))
    idx = coarse.repeat(cell, 0).repeat(cell, 1)[:h, :w]
    mask = rng.random((h, w)) < noise
    idx[mask] = rng.integers(0, k, int(mask.sum()))
    return values[idx].astype(np.uint8)


def _as_kind(img: np.ndarray, kind: str) -> np.ndarray:
    if kind == "rgb":
        table = np.random.default_rng(int(img.sum())).integers(0, 256, (256, 3), np.uint8)
        table[:, 0] = np.arange(256)  # distinct colours for distinct indices
        return table[img]
    if kind == "u16":
        return img.astype(np.uint16) * 257 + 3
    return img


def _assert_every_texel(layer, image: np.ndarray) -> None:
    h, w = image.shape[:2]
    for y in range(h):
        for x in range(w):
            got, want = layer.lookup(x, y), image[y, x]
            if image.ndim == 2:
                assert got == want and type(got) is type(want), (x, y, got, want)
            else:
                assert np.array_equal(got, want), (x, y, got, want)


@settings(max_examples=40, deadline=None)
@given(index_maps(), st.sampled_from(["hilbert", "morton"]),
       st.sampled_from(["index", "rgb", "u16"]), st.sampled_from([1 << 22, 16, 1]))
def test_scalar_lookup_equals_the_dense_image_in_every_layout(img, curve, kind, cap):
    # cap: QUICK_CELLS; 16 and 1 force quick cells of 32 texels a side and more.
    image = _as_kind(img, kind)
    layer = pack(image, curve)
    assert isinstance(layer, PackedLayer)
    layouts = [layer, layer.with_grid_bits(6), dataclasses.replace(layer, threads=1)]
    layouts += [PackedLayer.from_bytes(layer.to_bytes(format=f)) for f in FORMATS]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(scalar, "QUICK_CELLS", cap)
        for one in layouts:
            _assert_every_texel(one, image)


@settings(max_examples=15, deadline=None)
@given(index_maps(most=150), st.sampled_from(["hilbert", "morton", "auto"]),
       st.sampled_from(["compact", "seed"]))
def test_scalar_lookup_of_tiled_containers_equals_the_dense_image(img, curve, fmt):
    tiled = pack(img, curve, tile_bits=6)
    assert isinstance(tiled, TiledLayer)
    back = TiledLayer.from_bytes(tiled.to_bytes(format=fmt))
    # Joined (one table, the compiled call) and not (each tile's own scalar path).
    for one in (tiled, dataclasses.replace(back, join=False), back):
        _assert_every_texel(one, img)


@settings(max_examples=40, deadline=None)
@given(index_maps(), st.sampled_from(["hilbert", "morton"]), st.integers(0, 40),
       st.integers(0, 40))
def test_scalar_lookup_outside_the_layer_is_refused(img, curve, dx, dy):
    # Past the right edge inside the last quick cell too, and as the very first call
    # (before the quick cells exist).
    h, w = img.shape
    outside = [(w + dx, 0), (0, h + dy), (w + dx, h + dy), (-1 - dx, 0), (0, -1 - dy),
               (-1, h + dy), (w + dx, -1), (2**70, 0), (0, -(2**70))]
    for x, y in outside:
        layer = pack(img, curve)
        with pytest.raises(TerrathemeError, match=rf"\({x}, {y}\) is outside the {w} x {h}"):
            layer.lookup(x, y)
        with pytest.raises(TerrathemeError, match="outside"):
            layer.lookup(x, y)
        assert layer.lookup(w - 1, h - 1) == img[h - 1, w - 1]
        assert layer.lookup(0, 0) == img[0, 0]


@pytest.mark.parametrize("size", [(65, 65), (130, 70), (64, 64), (1, 1), (200, 9), (72, 136)])
@pytest.mark.parametrize("cap", [1 << 22, 4])
@pytest.mark.parametrize("join", [True, False])
def test_tiled_quick_cells_at_tile_edges_and_beyond_their_bound(size, cap, join):
    # Corner tiles of 1-8 texels have cells of another side (all looked up the long way);
    # cap 4: more cells than the bound, no quick cells at all.
    w, h = size
    rng = np.random.default_rng(w * 1000 + h)
    img = rng.integers(0, 3, (-(-h // 8), -(-w // 8))).repeat(8, 0).repeat(8, 1)[:h, :w]
    img = img.astype(np.uint8)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(scalar, "QUICK_CELLS", cap)
        tiled = dataclasses.replace(pack(img, tile_bits=6), join=join)
        _assert_every_texel(tiled, img)
    with pytest.raises(TerrathemeError, match=rf"\({w}, 0\) is outside"):
        tiled.lookup(w, 0)
    with pytest.raises(TerrathemeError, match=rf"\(0, {h}\) is outside"):
        tiled.lookup(0, h)
    with pytest.raises(TerrathemeError, match=r"\(-1, 0\) is outside"):
        tiled.lookup(-1, 0)


def test_numpy_integer_coordinates_take_the_same_answer_and_bools_are_refused():
    img = np.arange(12 * 9, dtype=np.uint8).reshape(9, 12) % 5
    for layer in (pack(img), pack(img, tile_bits=6)):
        for x, y in [(0, 0), (11, 8), (5, 3)]:
            for kind in (np.int64, np.int32, np.uint16, np.uint8):
                assert layer.lookup(kind(x), kind(y)) == img[y, x]
        for xs, ys in [(np.array([True]), np.array([0])), (True, 0), (0, False)]:
            with pytest.raises(TerrathemeError, match="integers"):
                layer.lookup(xs, ys)
