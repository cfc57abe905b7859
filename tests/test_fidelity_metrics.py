"""core.fidelity.metrics on synthetic images with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import TerrathemeError
from terratheme.core.fidelity import (
    colour_error,
    detail_energy,
    detail_placement,
    detail_ratio,
    structure_similarity,
)


def _lightness(v: float) -> float:
    """CIE L* of an sRGB grey level v in [0, 1] (IEC 61966-2-1, then CIE 1976)."""
    lin = v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4
    return 116 * lin ** (1 / 3) - 16 if lin > (6 / 29) ** 3 else lin * (29 / 6) ** 3 * 116 / 1


def _de2000_greys(l1: float, l2: float) -> float:
    """CIEDE2000 of two neutral colours: only the lightness term (Sharma et al. 2005, eq. 17)."""
    lbar = (l1 + l2) / 2
    sl = 1 + 0.015 * (lbar - 50) ** 2 / math.sqrt(20 + (lbar - 50) ** 2)
    return abs(l2 - l1) / sl


def _flat(v: float, shape=(40, 50)) -> np.ndarray:
    return np.full((*shape, 3), v, np.float32)


def test_colour_error_of_two_greys_is_their_lightness_difference():
    got = colour_error(_flat(0.3), _flat(0.6))
    assert got == pytest.approx(_de2000_greys(_lightness(0.3), _lightness(0.6)), rel=1e-3)
    assert colour_error(_flat(0.3), _flat(0.3)) == pytest.approx(0.0, abs=1e-6)


def test_colour_error_ignores_detail_finer_than_the_blur():
    yy, xx = np.mgrid[0:96, 0:96]
    checker = np.repeat(((xx + yy) % 2).astype(np.float32)[:, :, None], 3, axis=2)
    # A one-pixel checkerboard blurred at sigma 8 is its mean everywhere.
    assert colour_error(checker, _flat(0.5, (96, 96))) < 0.05
    assert colour_error(checker, _flat(0.5, (96, 96)), sigma=0.3) > 20


def test_colour_error_over_valid_pixels_only():
    photo = _flat(0.5, (64, 64))
    render = photo.copy()
    render[:, 32:] = 0.9
    valid = np.zeros((64, 64), bool)
    valid[:, :4] = True
    assert colour_error(render, photo, valid=valid) < 0.05
    assert colour_error(render, photo) > 5


def test_detail_of_flat_is_zero_and_contrast_scales_it_squared():
    rng = np.random.default_rng(0)
    photo = (0.25 + 0.5 * rng.random((64, 64, 3))).astype(np.float32)
    assert detail_energy(_flat(0.4)) == pytest.approx(0.0, abs=1e-12)
    assert detail_ratio(photo, photo) == pytest.approx(1.0)
    # Twice the contrast about the mean: the band-pass is linear, its energy x4.
    boosted = 0.5 + 2.0 * (photo - 0.5)
    assert detail_ratio(boosted, (photo - 0.5) + 0.5) == pytest.approx(4.0, rel=1e-4)
    assert detail_ratio(_flat(0.5, (64, 64)), photo) == pytest.approx(0.0, abs=1e-9)


def test_detail_placement_is_the_log2_energy_ratio_of_each_block():
    rng = np.random.default_rng(0)
    grain = (0.2 * (rng.random((64, 96, 3)) - 0.5)).astype(np.float32)
    # Twice the contrast: the band-pass is linear, each block's energy x4 (no floor).
    ratios = detail_placement(0.5 + 2.0 * grain, 0.5 + grain, floor=0.0)
    assert ratios.shape == (2, 3) and ratios.dtype == np.float32
    np.testing.assert_allclose(ratios, 2.0, atol=1e-4)
    # Grain on the left third only: flat blocks compare equal, the floor lowers the rest.
    photo = _flat(0.5, (64, 96))
    photo[:, :32] += grain[:, :32]
    ratios = detail_placement(0.5 + 2.0 * (photo - 0.5), photo)
    assert ((ratios[:, 0] > 1.8) & (ratios[:, 0] < 2.0)).all()
    np.testing.assert_allclose(ratios[:, 2], 0.0, atol=1e-6)  # the next holds the band's spill
    # The same grain in the wrong place: the whole-image ratio stays 1, the blocks do not.
    moved = _flat(0.5, (64, 96))
    moved[:, 64:] = photo[:, :32]
    assert detail_ratio(moved, photo) == pytest.approx(1.0, rel=0.05)
    ratios = detail_placement(moved, photo)
    assert ratios[:, 0].max() < -3 and ratios[:, 2].min() > 3


@given(st.integers(0, 2**31 - 1), st.integers(32, 80), st.integers(32, 80))
@settings(max_examples=25, deadline=None)
def test_detail_placement_is_zero_on_itself_and_antisymmetric(seed, h, w):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    b = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    b[: h // 2] = b[: h // 2] // 8 + 100  # calmer top half
    assert not detail_placement(a, a).any()
    np.testing.assert_allclose(detail_placement(a, b), -detail_placement(b, a), atol=1e-6)


def test_detail_placement_counts_whole_blocks_and_refuses_smaller_images():
    assert detail_placement(_flat(0.5, (70, 100)), _flat(0.5, (70, 100))).shape == (2, 3)
    assert detail_placement(_flat(0.5, (20, 20)), _flat(0.5, (20, 20)), block=8).shape == (2, 2)
    with pytest.raises(TerrathemeError, match="smaller than one 32 x 32 block"):
        detail_placement(_flat(0.5, (31, 100)), _flat(0.5, (31, 100)))


def test_detail_band_excludes_coarse_structure():
    xx = np.arange(256, dtype=np.float32)
    slow = 0.5 + 0.3 * np.sin(2 * np.pi * xx / 128)  # a 128 px wave: far below the band
    fast = 0.5 + 0.3 * np.sin(2 * np.pi * xx / 6)  # a 6 px wave: inside it
    to_img = lambda row: np.repeat(np.tile(row, (64, 1))[:, :, None], 3, axis=2)  # noqa: E731
    assert detail_energy(to_img(slow)) < 0.01 * detail_energy(to_img(fast))


def test_uint8_and_float_agree():
    rng = np.random.default_rng(1)
    a = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
    b = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
    assert colour_error(a, b) == pytest.approx(colour_error(a / 255.0, b / 255.0), rel=1e-5)
    assert detail_ratio(a, b) == pytest.approx(detail_ratio(a / 255.0, b / 255.0), rel=1e-5)


def test_errors():
    with pytest.raises(TerrathemeError, match="render is 50 x 40 but the photo is 5 x 4"):
        colour_error(_flat(0.1), _flat(0.1, (4, 5)))
    with pytest.raises(TerrathemeError, match=r"\(H, W, 3\) RGB image"):
        detail_energy(np.zeros((4, 4)))
    with pytest.raises(TerrathemeError, match="no detail"):
        detail_ratio(_flat(0.2), _flat(0.2))
    with pytest.raises(TerrathemeError, match="selects no pixel"):
        colour_error(_flat(0.1), _flat(0.1), valid=np.zeros((40, 50), bool))


def test_fidelity_summary_line():
    from terratheme.core.fidelity import fidelity

    rng = np.random.default_rng(2)
    photo = (0.25 + 0.5 * rng.random((64, 64, 3))).astype(np.float32)
    got = fidelity(photo, photo)
    assert got.colour_error == pytest.approx(0.0, abs=1e-6) and got.detail == pytest.approx(1.0)
    assert got.describe() == "dE8 0.0, detail 1.00"
    flat = fidelity(_flat(0.5, (64, 64)), _flat(0.5, (64, 64)))
    assert np.isnan(flat.detail) and "flat photo" in flat.describe()


def test_structure_similarity_of_identical_images_is_one_and_of_a_flat_copy_low():
    rng = np.random.default_rng(3)
    blocks = rng.integers(0, 256, (8, 8, 1), dtype=np.uint8)
    photo = np.repeat(np.repeat(np.repeat(blocks, 8, 0), 8, 1), 3, 2)
    assert structure_similarity(photo, photo, 4) == pytest.approx(1.0)
    flat = np.full_like(photo, int(photo.mean()))
    assert structure_similarity(flat, photo, 4) < 0.1


def test_structure_similarity_ignores_detail_inside_the_downscaled_pixel():
    # Each 8 x 8 block holds a different checkerboard of the same mean: alike at 1/8.
    board = (np.indices((64, 64)).sum(axis=0) % 2) * 200
    photo = np.repeat(board[:, :, None], 3, axis=2).astype(np.uint8)
    shifted = np.roll(photo, 1, axis=1)
    assert structure_similarity(shifted, photo, 8) == pytest.approx(1.0)
    assert structure_similarity(shifted, photo, 1) < 0.0


def test_structure_similarity_averages_whole_blocks_on_sides_off_the_factor():
    # Stripes of period 4 (two columns at 200, two at 0) average to one grey in every
    # aligned 4 x 4 block; a width of 66 (not a multiple of 4) must not make the blocks
    # straddle the period, which would read as coarse stripes.
    stripes = np.where(np.arange(66) % 4 < 2, 200, 0)
    photo = np.repeat(np.broadcast_to(stripes, (66, 66))[:, :, None], 3, axis=2).astype(np.uint8)
    grey = np.full_like(photo, 100)
    assert structure_similarity(photo, grey, 4) == pytest.approx(1.0, abs=1e-6)


def test_structure_similarity_sees_a_moved_road():
    photo = np.full((64, 64, 3), 200, np.uint8)
    photo[:, 24:32] = 40
    moved = np.full_like(photo, 200)
    moved[:, 40:48] = 40
    assert structure_similarity(moved, photo, 4) < 0.5 < structure_similarity(photo, photo, 4)


def _noise(seed: int, shape=(60, 70, 3)) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, shape, dtype=np.uint8)


@pytest.mark.parametrize("factor", [4, 8, 3])
@pytest.mark.parametrize("sigma", [8.0, 2.0])
def test_a_reference_scores_exactly_as_its_photo(factor, sigma):
    """Prepared once (issue 37), the photo's side gives the very same scores."""
    from terratheme.core.fidelity import reference

    photo, render = _noise(1), _noise(2)
    ref = reference(photo, sigmas=(8.0,), factors=(4, 8))
    assert structure_similarity(render, ref, factor) == structure_similarity(render, photo,
                                                                             factor)
    assert colour_error(render, ref, sigma=sigma) == colour_error(render, photo, sigma=sigma)
    valid = np.zeros(photo.shape[:2], bool)
    valid[5:20, 10:40] = True
    assert (colour_error(render, ref, valid=valid)
            == colour_error(render, photo, valid=valid))


def test_a_reference_downscales_the_photo_once_for_many_renders(monkeypatch):
    import terratheme.core.fidelity.metrics as metrics

    photo = _noise(3)
    ref = metrics.reference(photo)
    sizes = []
    real = metrics.cv2.resize

    def counting(img, size, **kwargs):
        sizes.append(img.shape)
        return real(img, size, **kwargs)

    monkeypatch.setattr(metrics.cv2, "resize", counting)
    for seed in range(3):
        structure_similarity(_noise(10 + seed), ref, 4)
        structure_similarity(_noise(10 + seed), ref, 8)
    assert len(sizes) == 6  # the renders only


def test_a_reference_of_another_size_is_refused():
    from terratheme.core.fidelity import reference

    ref = reference(_noise(1))
    with pytest.raises(TerrathemeError, match="render is 50 x 40"):
        structure_similarity(_noise(2, (40, 50, 3)), ref)
    with pytest.raises(TerrathemeError, match="render is 50 x 40"):
        colour_error(_noise(2, (40, 50, 3)), ref)
