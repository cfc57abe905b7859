"""Edge-aware, confidence-weighted regularisation (Regularisation.EDGE)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.classify import (
    Classifier,
    Regularisation,
    RegulariseOptions,
    train_classifier,
)
from terratheme.core.classify.regularise import edge_aware_probabilities, edge_reach, regularise
from terratheme.core.errors import TerrathemeError


def two_colour_guide(h=12, w=24, edge=12):
    """Lab guide: dark green left of column ``edge``, light grey from it on."""
    lab = np.empty((h, w, 3), np.float32)
    lab[:, :edge] = (40.0, -30.0, 30.0)
    lab[:, edge:] = (80.0, 0.0, 0.0)
    return lab


def leaning_probs(h=12, w=24, sure_left=8, edge=12):
    """Class 0 sure left of ``sure_left``, class 1 sure from ``edge``; between, a weak lean to 1."""
    probs = np.empty((h, w, 2), np.float32)
    probs[:, :sure_left] = (0.95, 0.05)
    probs[:, sure_left:edge] = (0.45, 0.55)
    probs[:, edge:] = (0.05, 0.95)
    return probs


def test_constant_probabilities_stay_constant():
    rng = np.random.default_rng(3)
    lab = rng.uniform(0, 100, (20, 30, 3)).astype(np.float32)
    probs = np.broadcast_to(np.array([0.2, 0.5, 0.3], np.float32), (20, 30, 3)).copy()
    out = edge_aware_probabilities(probs, lab, 8.0, 10.0)
    np.testing.assert_allclose(out, probs, atol=1e-5)


def test_label_boundary_moves_onto_the_image_edge():
    # Before: arg-max changes at column 8 (the unsure pixels lean to class 1).
    lab, probs = two_colour_guide(), leaning_probs()
    assert (probs.argmax(2)[:, 8:12] == 1).all()
    out = edge_aware_probabilities(probs, lab, 8.0, 10.0)
    # After: the unsure pixels share the colour of the sure class-0 pixels: the
    # boundary sits on the colour edge at column 12.
    assert (out.argmax(2)[:, :12] == 0).all() and (out.argmax(2)[:, 12:] == 1).all()


def test_without_an_edge_the_sure_side_spreads_further():
    # Same probabilities on a flat guide: nothing stops the averaging at column 12,
    # so the sure class-1 pixels pull the unsure ones (and more) their way.
    probs = leaning_probs()
    flat = np.full((12, 24, 3), 50.0, np.float32)
    out = edge_aware_probabilities(probs, flat, 8.0, 10.0)
    assert not np.allclose(out, probs, atol=0.05)
    assert (out.argmax(2)[:, 8:12] == out.argmax(2)[:, 8:9]).all()


def test_texture_channel_keeps_equal_colours_apart():
    # Equal Lab everywhere; the left half is textured (block std 25), the right flat.
    lab = np.full((12, 24, 3), 50.0, np.float32)
    texture = np.zeros((12, 24), np.float32)
    texture[:, :12] = 25.0
    out = edge_aware_probabilities(leaning_probs(), lab, 8.0, 10.0, texture)
    assert (out.argmax(2)[:, :12] == 0).all() and (out.argmax(2)[:, 12:] == 1).all()


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 9), st.integers(1, 9), st.integers(1, 5), st.integers(0, 2**31 - 1))
def test_rows_stay_on_the_simplex(h, w, c, seed):
    rng = np.random.default_rng(seed)
    probs = rng.dirichlet(np.ones(c), (h, w)).astype(np.float32)
    lab = rng.uniform(-50, 100, (h, w, 3)).astype(np.float32)
    out = regularise(probs, lab, RegulariseOptions(method=Regularisation.EDGE),
                     texture=rng.uniform(0, 20, (h, w)).astype(np.float32))
    assert out.shape == probs.shape and out.dtype == np.float32
    assert (out >= 0).all()
    np.testing.assert_allclose(out.sum(2), 1.0, atol=1e-5)


def test_reach_by_hand():
    # Box radii 3 * 8 * (4, 2, 1) / sqrt(63) = 12.10, 6.05, 3.02: 21.17 -> 22.
    assert edge_reach(8.0) == math.ceil(24.0 * 7.0 / math.sqrt(63.0)) == 22
    assert RegulariseOptions(method=Regularisation.EDGE).halo == 23


def test_reach_bounds_the_filter():
    # A single sure pixel moves values at most edge_reach pixels away, along both axes
    # (elsewhere only float rounding of the filter's running sums, ~1e-6).
    probs = np.full((1, 80, 2), 0.5, np.float32)
    probs[0, 40] = (1.0, 0.0)
    out = edge_aware_probabilities(probs, np.zeros((1, 80, 3), np.float32), 4.0, 10.0)
    moved = np.flatnonzero(np.abs(out[0, :, 0] - 0.5) > 1e-4)
    assert moved.min() >= 40 - edge_reach(4.0) and moved.max() <= 40 + edge_reach(4.0)
    assert moved.max() > 40 + edge_reach(4.0) // 2


@pytest.mark.parametrize("bad", [dict(edge_sigma_spatial=0.0), dict(edge_sigma_colour=-1.0)])
def test_bad_edge_sigmas_are_clear_errors(bad):
    with pytest.raises(TerrathemeError, match="edge regularisation sigmas"):
        RegulariseOptions(method=Regularisation.EDGE, **bad)


def test_edge_default_tiles_do_not_show(block_photo):
    # Random blocks of three colours with noise; small tiles must give the whole-photo labels.
    photo, blocks = block_photo(np.random.default_rng(11), (9, 11), 24, 8)
    mask = np.zeros(blocks.shape, np.uint8)
    mask[12::24, 6:18] = blocks[12::24, 6:18] + 1
    model = train_classifier([(photo, mask)])
    assert model.options.regularisation.method is Regularisation.EDGE
    whole = model.predict(photo).labels
    tiled = Classifier(model.forest, model.classes, replace(model.options, tile=64),
                       model.class_weights).predict(photo).labels
    np.testing.assert_array_equal(tiled, whole)
    assert (whole == blocks + 1).mean() > 0.9
