"""Issue 18: the family of prefiltered copies, built level by level
(core/perspective/family.py), its memory for any aspect ratio, and the
power-of-two grid (core/perspective/texture.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.perspective import Camera, FilterOptions, PreparedTexture
from terratheme.core.perspective.family import build_family, family_layout, skew_values
from terratheme.core.perspective.texture import (
    power_of_two_grid,
    power_of_two_side,
    stored_texture,
)


def _random(h, w, c=2, seed=0):
    return np.random.default_rng(seed).random((h, w, c)).astype(np.float32)


def _direct_cell(tex, a, b, tau, m, k):
    """Cell (m, k) of copy (a, b, tau) toward U by its definition: the mean over the
    texel rows of the cell's 2^b band of the bilinear texture read on the lines of
    slope tau through the texel columns' centres of its 2^a span."""
    rows = tex.shape[0]
    s, t = 1 << a, 1 << b
    uk = (k + 0.5) * s
    acc = 0.0
    for r in range(m * t, (m + 1) * t):
        for j in range(k * s, (k + 1) * s):
            y = r + tau * (j + 0.5 - uk)
            j0 = int(np.floor(y))
            f = y - j0
            acc = acc + (1 - f) * tex[j0 % rows, j] + f * tex[(j0 + 1) % rows, j]
    return acc / (s * t)


def test_skew_sets():
    np.testing.assert_allclose(skew_values(1), [0.0])
    np.testing.assert_allclose(skew_values(2), [-1.0, 0.0, 1.0])
    np.testing.assert_allclose(skew_values(3), [-1.0, -0.5, 0.0, 0.5, 1.0])
    np.testing.assert_allclose(skew_values(2, 2), [-1.0, -0.5, 0.0, 0.5, 1.0])


def test_mip_levels_are_block_means_and_skew_zero_is_column_pairs():
    tex = _random(8, 8)
    fam = build_family(tex, 2, 1)
    for lvl in range(4):
        r = 8 >> lvl
        want = tex.reshape(r, 1 << lvl, r, 1 << lvl, 2).mean(axis=(1, 3))
        np.testing.assert_allclose(fam.copy(0, lvl, lvl), want, atol=1e-6)
    # lambda = 2 toward U, skew 0: pairs of columns; toward V: pairs of rows, transposed
    np.testing.assert_allclose(fam.copy(0, 1, 0), tex.reshape(8, 4, 2, 2).mean(axis=2),
                               atol=1e-6)
    np.testing.assert_allclose(fam.copy(1, 1, 0),
                               tex.reshape(4, 2, 8, 2).mean(axis=1).transpose(1, 0, 2),
                               atol=1e-6)


@pytest.mark.parametrize("so", [1, 2])
def test_every_skewed_copy_is_its_definition(so):
    # level by level (shear, then 4-cell means up the diagonal) equals the direct mean
    tex = _random(16, 32, c=1, seed=3)
    fam = build_family(tex, 3, so)
    checked = 0
    for a in range(1, 6):
        for b in range(0, 5):
            if fam.start[0, a, b] < 0 or a == b:
                continue
            taus = skew_values(a - b, so) if fam.count[0, a, b] > 1 else [0.0]
            for s, tau in enumerate(taus):
                copy = fam.copy(0, a, b, s)
                for m, k in ((0, 0), (copy.shape[0] - 1, copy.shape[1] - 1),
                             (copy.shape[0] // 2, copy.shape[1] // 3)):
                    want = _direct_cell(tex[:, :, 0].astype(np.float64), a, b, tau, m, k)
                    assert copy[m, k, 0] == pytest.approx(want, abs=2e-6)
                    checked += 1
    assert checked > 60


def test_toward_v_copies_are_the_toward_u_copies_of_the_transpose():
    tex = _random(16, 8, seed=5)
    fam = build_family(tex, 3, 1)
    fam_t = build_family(np.ascontiguousarray(tex.transpose(1, 0, 2)), 3, 1)
    for a in range(1, 5):
        for b in range(0, 4):
            if fam.start[1, a, b] >= 0 and a != b:
                for s in range(int(fam.count[1, a, b])):
                    np.testing.assert_allclose(fam.copy(1, a, b, s), fam_t.copy(0, a, b, s),
                                               atol=1e-6)


def test_memory_is_accounted_by_hand():
    # 16 x 16, k = 2, seed skews: mip levels 256 + 64 + 16 + 4 + 1; per orientation
    # (a, b) with a - b = 1 (1 skew) and 2 (3 skews), (N >> b) x (N >> a) cells;
    # b = 4 is the exhausted cross side: nothing longer than 16 along exists there
    per_orientation = 0
    for b in range(5):
        for a in range(b + 1, min(4, b + 2) + 1):
            skews = 1 if b == 4 else len(skew_values(a - b))
            per_orientation += skews * (16 >> b) * (16 >> a)
    fam = build_family(np.zeros((16, 16, 3), np.float32), 2, 1, dtype=np.uint8)
    assert fam.buf.shape[0] == 341 + 2 * per_orientation
    assert fam.nbytes == fam.buf.shape[0] * 3


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 13), st.integers(0, 13))
def test_memory_follows_the_texel_count_for_any_aspect_ratio(p, q):
    # at most 8 cells per texel of the grid (the seed's (k + 1) 4/3 plus the extra
    # skews), however long and thin: a 8192 x 1 strip is about 8 x 8192 cells
    _, _, total = family_layout((1 << p, 1 << q), 4, 1)
    assert total <= 8.0 * (1 << p) * (1 << q)


@pytest.mark.parametrize("shape", [(1, 4096), (4096, 1), (2, 2048)])
def test_thin_strips_build_small_and_render(shape):
    tex = np.random.default_rng(0).integers(0, 256, shape + (3,), dtype=np.uint8)
    pt = PreparedTexture(tex)
    assert pt.family().nbytes <= 8 * 3 * tex.shape[0] * tex.shape[1]
    img = pt.render(Camera(height=3, pitch=5, yaw=20), (64, 36)).image
    assert np.all(np.isfinite(img)) and img.min() >= 0 and img.max() <= 1


def test_strip_far_footprints_read_the_strip_mean():
    # V = 1000 y: every pixel winds round the 1-texel-tall strip; along U a 64-texel span
    from terratheme.core.perspective import PlaneMapping

    row = _random(1, 64, c=1, seed=2)
    img = PreparedTexture(row).render(PlaneMapping(64, 0, 0, 0, 1000, 0, 0, 0, 1), (3, 2)).image
    np.testing.assert_allclose(img, row.mean(), atol=1e-5)


def test_progress_counts_every_cell_once():
    calls = []
    fam = build_family(_random(32, 16), 3, 1, progress=lambda d, t: calls.append((d, t)))
    done = [d for d, _ in calls]
    assert done == sorted(done) and calls[-1] == (fam.buf.shape[0], fam.buf.shape[0])


def test_eight_bit_family_is_within_two_units_of_the_float_one():
    # each level is rounded once, from rounded parents: the errors stay small
    tex = np.random.default_rng(4).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    f8 = build_family(tex, 4, 1, dtype=np.uint8)
    ff = build_family(tex.astype(np.float32), 4, 1)
    diff = f8.buf.astype(np.float64) - ff.buf
    assert np.abs(diff).max() <= 2.0
    assert np.sqrt(np.mean(diff**2)) < 0.45


def test_family_refuses_other_sides_and_oversampling():
    with pytest.raises(TerrathemeError, match="power-of-two"):
        build_family(np.zeros((6, 8, 1), np.float32), 2)
    with pytest.raises(TerrathemeError, match="skew_oversampling"):
        build_family(np.zeros((8, 8, 1), np.float32), 2, 4)


@pytest.mark.parametrize("n, want", [(1, 1), (2, 2), (3, 4), (5, 4), (6, 8), (1126, 1024),
                                     (1449, 1024), (1500, 2048), (4096, 4096)])
def test_power_of_two_side(n, want):
    assert power_of_two_side(n) == want


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 1 << 20))
def test_a_side_grows_by_at_most_1_37_and_shrinks_by_at_most_1_47(n):
    assert n / 1.47 <= power_of_two_side(n) <= 1.37 * n


def test_power_of_two_grid_resamples_each_side_and_keeps_the_range():
    tex = stored_texture(np.random.default_rng(1).integers(0, 256, (3, 11, 3), dtype=np.uint8))
    grid, su, sv = power_of_two_grid(tex)
    assert grid.shape == (4, 8, 3) and grid.dtype == np.uint8
    assert (su, sv) == (8 / 11, 4 / 3)
    assert grid.min() >= tex.texels.min() and grid.max() <= tex.texels.max()
    # a power-of-two texture is its own grid
    same = stored_texture(np.zeros((4, 16, 1), np.float32))
    assert power_of_two_grid(same)[0] is same.texels


def test_resampled_constant_stays_constant():
    tex = stored_texture(np.full((37, 23, 2), 0.3, np.float32))
    np.testing.assert_allclose(power_of_two_grid(tex)[0], 0.3, atol=1e-6)


def test_prepared_texture_memory_is_family_plus_input():
    tex = np.random.default_rng(0).integers(0, 256, (48, 40, 3), dtype=np.uint8)
    pt = PreparedTexture(tex, FilterOptions())
    assert pt.grid_size == (32, 64)
    assert pt.memory_bytes() == pt.family().nbytes + tex.nbytes
    assert pt.memory_bytes() <= 48 * 48 * 40


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 3000), st.integers(1, 3000))
def test_an_rgb_texture_of_any_size_costs_at_most_48_bytes_per_texel(w, h):
    from terratheme.core.perspective.family import family_layout

    cells = family_layout((power_of_two_side(w), power_of_two_side(h)), 4, 1)[2]
    assert cells * 3 + w * h * 3 <= 48 * w * h
