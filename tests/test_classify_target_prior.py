"""Class shares of a new photo by EM (Saerens et al. 2002) and their use at prediction."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.classify import SupervisedOptions, train_classifier
from terratheme.core.classify.prior import em_shares
from terratheme.core.errors import TerrathemeError


def gaussian_posteriors(x: np.ndarray, means, priors) -> np.ndarray:
    """Exact posteriors of unit-variance 1-D Gaussian classes under ``priors``."""
    like = np.exp(-0.5 * (x[:, None] - np.asarray(means)[None, :]) ** 2)
    post = like * np.asarray(priors)[None, :]
    return post / post.sum(1, keepdims=True)


@pytest.mark.parametrize("true_shares", [(0.8, 0.2), (0.5, 0.5), (0.15, 0.85)])
def test_em_recovers_shifted_class_shares(true_shares):
    # Two overlapping classes; the classifier was trained with priors 1/2, 1/2;
    # the new photo has other shares. EM's estimate converges to them.
    rng = np.random.default_rng(0)
    n = 40_000
    k = rng.random(n) < true_shares[0]
    x = np.where(k, rng.normal(0.0, 1.0, n), rng.normal(1.5, 1.0, n))
    probs = gaussian_posteriors(x, (0.0, 1.5), (0.5, 0.5))
    shares = em_shares(probs, np.array([0.5, 0.5]), iterations=500, tol=1e-9)
    np.testing.assert_allclose(shares, true_shares, atol=0.02)
    # Classify and count is biased towards 1/2 on overlapping classes; EM is not.
    counted = np.bincount(probs.argmax(1), minlength=2) / n
    assert abs(shares[0] - true_shares[0]) <= abs(counted[0] - true_shares[0]) + 1e-3


def test_em_of_sure_posteriors_is_the_count_and_of_nothing_the_training_priors():
    probs = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(em_shares(probs, np.full(3, 1 / 3)), [0.75, 0.0, 0.25])
    np.testing.assert_allclose(em_shares(np.zeros((0, 2)), np.array([3.0, 1.0])), [0.75, 0.25])


def test_em_first_step_by_hand():
    # One step from t = (1/2, 1/2): pi = mean of the posteriors (eq. 2.10 with pi = t).
    probs = np.array([[0.9, 0.1], [0.6, 0.4]])
    np.testing.assert_allclose(em_shares(probs, np.array([0.5, 0.5]), iterations=1),
                               [0.75, 0.25])


def test_target_prior_needs_balanced_training_and_a_power_in_0_1():
    with pytest.raises(TerrathemeError, match="target_prior_power needs balance"):
        SupervisedOptions(target_prior_power=0.5, balance=False)
    with pytest.raises(TerrathemeError, match="target_prior_power must be in 0..1"):
        SupervisedOptions(target_prior_power=1.5)


def test_target_prior_moves_unsure_pixels_to_the_photos_common_class():
    # Train on a photo of dark and bright blocks; classify a photo that is mostly
    # dark with mid-grey blocks the forest is torn on: re-estimated shares favour dark.
    rng = np.random.default_rng(1)
    train = np.zeros((64, 128, 3), np.uint8)
    train[:, :64], train[:, 64:] = 60, 180
    mask = np.zeros((64, 128), np.uint8)
    mask[:, :64], mask[:, 64:] = 1, 2
    train = np.clip(train + rng.normal(0, 6, train.shape), 0, 255).astype(np.uint8)
    target = np.full((96, 96, 3), 60, np.uint8)
    target[:, 80:] = 180
    target[8:24, 8:24] = 120   # halfway: unsure
    target = np.clip(target + rng.normal(0, 6, target.shape), 0, 255).astype(np.uint8)
    off = train_classifier([(train, mask)], SupervisedOptions(adapt=False))
    on = train_classifier([(train, mask)], SupervisedOptions(adapt=False,
                                                             target_prior_power=1.0))
    a, b = off.predict(target), on.predict(target)
    assert set(np.unique(b.labels)) <= {1, 2}
    # Everything sure stays; the unsure block leans to the photo's common class.
    assert (b.labels[:, 30:70] == 1).all() and (b.labels[:, 84:] == 2).all()
    assert (b.labels[10:22, 10:22] == 1).mean() >= (a.labels[10:22, 10:22] == 1).mean()
