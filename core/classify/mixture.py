"""Themes as a Gaussian mixture: per-theme, per-feature variances (design.md §3).

k-means gives every theme the same round spread (:func:`isotropic_variances`). A theme
of another hue inside a textured one needs its own spread per feature, so
:func:`fit_diagonal_mixture` refits the themes as a diagonal ``GaussianMixture`` from
given labels. :func:`posterior_fn` classifies under either spread.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

#: Smallest variance of any feature of any theme, in Delta-E^2 (flat themes stay sharp).
VARIANCE_FLOOR = 1.0
#: Most samples the mixture is fitted on (every m-th of a larger sample; labels for all).
MIXTURE_SAMPLES = 8000
#: Most EM steps of the fit.
MIXTURE_ITERATIONS = 100


def isotropic_variances(within: float, centres: np.ndarray) -> np.ndarray:
    """The k-means spread (K, F) float32: ``max(within / F, VARIANCE_FLOOR)`` everywhere,
    ``within`` the pooled mean squared distance to the nearest of ``centres`` (K, F)."""
    k, f = centres.shape
    return np.full((k, f), max(within / f, VARIANCE_FLOOR), np.float32)


def _mixture(means: np.ndarray, weights: np.ndarray, variances: np.ndarray):
    """A fitted diagonal ``GaussianMixture`` with these parameters (K, F), (K,), (K, F)."""
    from sklearn.mixture import GaussianMixture

    gm = GaussianMixture(len(means), covariance_type="diag")
    gm.means_ = np.asarray(means, np.float64)
    gm.weights_ = np.maximum(np.asarray(weights, np.float64), 1e-6)
    gm.weights_ /= gm.weights_.sum()
    gm.covariances_ = np.asarray(variances, np.float64)
    gm.precisions_cholesky_ = 1.0 / np.sqrt(gm.covariances_)
    return gm


def fit_diagonal_mixture(samples: np.ndarray, start: np.ndarray):
    """Diagonal Gaussian mixture (EM) of weighted ``samples`` (n, F) float32 started from
    themes ``start`` (n,) int, 0..K-1, each present. Deterministic.

    One ``GaussianMixture`` EM step at a time, variances floored at
    :data:`VARIANCE_FLOOR` after each (``reg_covar`` would add a constant to all), on the
    varying features and at most :data:`MIXTURE_SAMPLES` samples. Returns labels (n,)
    int, means (K, F) float32, weights (K,) float64, variances (K, F) float32.
    """
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.mixture import GaussianMixture

    k, f = int(start.max()) + 1, samples.shape[1]
    # Weight-0 columns are constant: left out of the fit, given the floor variance.
    active = np.flatnonzero(samples.min(0) < samples.max(0))
    x = samples[:, active].astype(np.float64)
    step = max(1, -(-len(x) // MIXTURE_SAMPLES))
    fit_x, fit_start = x[::step], start[::step]
    if not (np.bincount(fit_start, minlength=k) > 0).all():
        fit_x, fit_start = x, start
    # The start: shares, means and floored variances of the labelled themes.
    resp = np.eye(k)[fit_start]
    nk = resp.sum(0)
    means = resp.T @ fit_x / nk[:, None]
    variances = np.maximum(resp.T @ (fit_x * fit_x) / nk[:, None] - means * means,
                           VARIANCE_FLOOR)
    gm = GaussianMixture(k, covariance_type="diag", max_iter=1, warm_start=True,
                         weights_init=nk / nk.sum(), means_init=means,
                         precisions_init=1.0 / variances, random_state=0)
    previous = -np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        for _ in range(MIXTURE_ITERATIONS):
            gm.fit(fit_x)
            gm.covariances_ = np.maximum(gm.covariances_, VARIANCE_FLOOR)
            gm.precisions_cholesky_ = 1.0 / np.sqrt(gm.covariances_)
            if gm.lower_bound_ - previous < gm.tol:
                break
            previous = gm.lower_bound_
    full_means = np.tile(samples[0].astype(np.float32), (k, 1))
    full_means[:, active] = gm.means_
    full_variances = np.full((k, f), VARIANCE_FLOOR, np.float32)
    full_variances[:, active] = gm.covariances_
    return gm.predict(x), full_means, gm.weights_, full_variances


def posterior_fn(centres: np.ndarray, sizes: np.ndarray, variances: np.ndarray,
                 weights: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``(h, w, F) float32 -> (h, w, K) float32``: each theme's posterior under the mixture
    of means ``centres`` and ``variances`` (K, F) and weights ``sizes`` (K,), the
    features multiplied by ``weights`` (F,) first."""
    gm = _mixture(centres, sizes, variances)
    k, f = centres.shape

    def probs(feats: np.ndarray) -> np.ndarray:
        h, w, _ = feats.shape
        p = gm.predict_proba(feats.reshape(-1, f) * weights)
        return p.reshape(h, w, k).astype(np.float32)

    return probs
