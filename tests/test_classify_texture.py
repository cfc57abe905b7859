"""Structure features (core.classify.texture): known answers on drawn photos."""

from __future__ import annotations

import json

import numpy as np
import pytest
from classify_cases import assert_tiles_match_whole
from terratheme.core.classify import SupervisedOptions
from terratheme.core.classify.features import FeatureOptions, image_features
from terratheme.core.classify.lab import full_lab
from terratheme.core.classify.model_options import options_from_json, options_to_json
from terratheme.core.errors import TerrathemeError

SIGMAS = (1.0, 2.0)
OPTIONS = FeatureOptions(sigmas=SIGMAS, structure=True)


def structure_of(photo: np.ndarray) -> np.ndarray:
    """The 1 + len(SIGMAS) structure features (they come last)."""
    return image_features(photo, OPTIONS)[2][:, :, -(1 + len(SIGMAS)):]


def stripes(h: int, w: int, period: int, low: int, high: int, vertical: bool) -> np.ndarray:
    axis = np.arange(w if vertical else h)
    line = np.where((axis // (period // 2)) % 2 == 0, low, high).astype(np.uint8)
    img = np.broadcast_to(line[None, :] if vertical else line[:, None], (h, w))
    return np.repeat(img[:, :, None], 3, axis=2).copy()


def test_count_and_position():
    assert OPTIONS.n_features == FeatureOptions(sigmas=SIGMAS).n_features + 1 + len(SIGMAS)
    plain = FeatureOptions(sigmas=SIGMAS)
    photo = np.random.default_rng(1).integers(0, 256, (48, 40, 3), dtype=np.uint8)
    _lab, _std, without = image_features(photo, plain)
    np.testing.assert_array_equal(image_features(photo, OPTIONS)[2][:, :, :without.shape[2]],
                                  without)


def test_flat_photo_has_no_structure():
    out = structure_of(np.full((40, 48, 3), 120, np.uint8))
    np.testing.assert_allclose(out, 0.0, atol=1e-6)


def test_parallel_lines_are_coherent_in_either_direction():
    # Stripes 32 px wide: the coarse lightness varies along one axis only.
    for vertical in (True, False):
        out = structure_of(stripes(128, 128, 64, 60, 200, vertical))
        coherence = out[:, :, 1:]
        # Away from the flat stripe centres the tensor has one direction only.
        strong = out[:, :, 0] > 0  # blocks on a stripe edge
        assert strong.any()
        assert (coherence[strong] > 0.95).all()


def test_coherence_ignores_contrast_but_edge_density_does_not():
    low = structure_of(stripes(96, 96, 32, 100, 140, True))
    high = structure_of(stripes(96, 96, 32, 60, 220, True))
    np.testing.assert_allclose(low[:, :, 1:], high[:, :, 1:], atol=0.02)
    assert high[:, :, 0].max() > 2.0 * low[:, :, 0].max()


def test_isotropic_noise_is_less_coherent_than_lines():
    rng = np.random.default_rng(4)
    noise = np.repeat(rng.integers(0, 256, (128, 128, 1), dtype=np.uint8), 3, axis=2)
    lines = stripes(128, 128, 16, 0, 255, True)
    assert structure_of(noise)[:, :, 2].mean() < 0.3
    # Stripes of 8 px average out in 8 px blocks: compare the edge density instead.
    assert structure_of(noise)[:, :, 0].mean() > 0 and structure_of(lines)[:, :, 0].mean() > 0


def test_edge_density_is_the_block_mean_of_the_gradient():
    photo = np.full((16, 16, 3), 100, np.uint8)
    photo[:, 8:] = 200  # one vertical step between block columns 0 and 1
    out = structure_of(photo)
    step = full_lab(photo)[0, 8, 0] - full_lab(photo)[0, 7, 0]
    # Sobel 1/8: |gx| = step / 2 on the two pixel columns beside the step, 0 elsewhere.
    np.testing.assert_allclose(out[:, :, 0], step / 2 / 8, rtol=1e-4)


def test_tiles_with_the_halo_reproduce_the_whole_photo():
    photo = np.random.default_rng(6).integers(0, 256, (72, 96, 3), dtype=np.uint8)
    assert_tiles_match_whole(photo, OPTIONS, 32)


def test_model_options_keep_the_flag_and_old_files_read_without_it():
    d = json.loads(json.dumps(options_to_json(SupervisedOptions())))  # as a file holds it
    assert options_from_json(d).features.structure
    del d["features"]["structure"]
    assert not options_from_json(d).features.structure
    d["features"]["structure"] = "yes"
    with pytest.raises((ValueError, TerrathemeError)):
        options_from_json(d)


def test_context_blur_takes_more_channels_than_one_opencv_call():
    # 130 class probabilities (classify --themes 130): each channel blurred as alone.
    import cv2
    from terratheme.core.classify.texture import context_blur

    rng = np.random.default_rng(3)
    probs = rng.random((12, 17, 130)).astype(np.float32)
    out = context_blur(probs, 1.5)
    assert out.shape == probs.shape and out.dtype == np.float32
    for c in (0, 127, 128, 129):
        alone = cv2.GaussianBlur(np.ascontiguousarray(probs[:, :, c]), (11, 11), 1.5,
                                 borderType=cv2.BORDER_REFLECT_101)
        np.testing.assert_allclose(out[:, :, c], alone, rtol=1e-6, atol=1e-7)


def test_unsupervised_with_130_themes_is_not_an_opencv_error():
    from terratheme.core.classify import classify_unsupervised

    rng = np.random.default_rng(4)
    photo = rng.integers(0, 256, (160, 160, 3), dtype=np.uint8)
    result = classify_unsupervised(photo, themes=130)
    assert result.labels.shape == (160, 160)
