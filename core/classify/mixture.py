"""Themes as a Gaussian mixture: per-theme, per-feature variances (design.md §3).

k-means gives every theme the same round spread (the pooled within-theme
variance, :func:`isotropic_variances`). That is right while the themes differ
mostly in the same features, and it is what the criterion for K
(:mod:`core.classify.unsupervised`) assumes. A theme of another hue inside a
textured one is different: the textured theme spreads widely in lightness and
little in chroma, the other theme the reverse, and a round spread gives the
textured theme's dark and light pixels to whichever centre is nearest in
lightness. :func:`fit_diagonal_mixture` refits the themes as a mixture of
Gaussians with diagonal covariances (EM), started from given
labels, so each theme keeps its own spread per feature. :func:`posterior_fn`
classifies under either kind of spread.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Smallest variance of any feature of any theme, in Delta-E^2 (flat themes stay sharp).
VARIANCE_FLOOR = 1.0
#: Most samples the mixture's EM sees (every m-th of a larger sample; labels for all).
MIXTURE_SAMPLES = 8000
#: EM stops when the mean log-likelihood per sample gains less than this...
MIXTURE_TOLERANCE = 1e-3
#: ... or after this many iterations.
MIXTURE_ITERATIONS = 100


def isotropic_variances(within: float, centres: np.ndarray) -> np.ndarray:
    """The k-means spread: the pooled per-feature variance ``within / F`` for every theme.

    Parameters
    ----------
    within : float
        Pooled mean squared distance to the nearest centre, ``W_K``.
    centres : (K, F) ndarray

    Returns
    -------
    variances : (K, F) float32 ndarray
        ``max(within / F, VARIANCE_FLOOR)`` everywhere.
    """
    k, f = centres.shape
    return np.full((k, f), max(within / f, VARIANCE_FLOOR), np.float32)


def log_joint(x: np.ndarray, means: np.ndarray, weights: np.ndarray,
              variances: np.ndarray) -> np.ndarray:
    """``log(weight_k) + log N(x | mean_k, diag(variance_k))`` up to a constant.

    Parameters
    ----------
    x : (n, F) ndarray
    means, variances : (K, F) ndarrays
    weights : (K,) ndarray

    Returns
    -------
    (n, K) ndarray, the dtype of ``x``
    """
    inv = (1.0 / variances).astype(x.dtype)
    # log w_k - 0.5 * (sum of log variances + Mahalanobis distance), the distance as
    # x^2 / v - 2 x.c / v + c^2 / v (diagonal v).
    const = (np.log(np.maximum(weights, 1e-6))
             - 0.5 * np.log(variances.astype(np.float64)).sum(1)).astype(x.dtype)
    d2 = (x * x) @ inv.T - 2.0 * x @ (means * inv).T.astype(x.dtype)
    d2 += (means * means * inv).sum(1).astype(x.dtype)[None]
    return const[None] - 0.5 * np.maximum(d2, 0.0)


def fit_diagonal_mixture(samples: np.ndarray, start: np.ndarray):
    """EM of a diagonal-covariance Gaussian mixture started from labels.

    Parameters
    ----------
    samples : (n, F) float32 ndarray
        Weighted features.
    start : (n,) int ndarray
        Starting theme of each sample, ``0..K-1``, every theme present.

    EM (Dempster, Laird & Rubin 1977) from an M step on the labels, on the
    features that vary and on every m-th sample, at most
    :data:`MIXTURE_SAMPLES` (all of them if that would miss a theme), until the
    mean log-likelihood gains less than :data:`MIXTURE_TOLERANCE`; variances
    floored at :data:`VARIANCE_FLOOR`. Deterministic. (scikit-learn's
    ``GaussianMixture`` does the same, but importing it costs ``convert`` about
    a second; OpenCV's EM took 1-2 s per fit here.)

    Returns
    -------
    labels : (n,) int ndarray
        Most probable theme of each sample under the fitted mixture.
    means : (K, F) float32 ndarray
    weights : (K,) float64 ndarray
        Mixture weights.
    variances : (K, F) float32 ndarray
        Per-theme, per-feature variances (at least :data:`VARIANCE_FLOOR`).
    """
    k, f = int(start.max()) + 1, samples.shape[1]
    # Features that vary (weight-0 columns are constant) and at most MIXTURE_SAMPLES samples.
    active = np.flatnonzero(samples.min(0) < samples.max(0))
    x = samples[:, active].astype(np.float64)
    step = max(1, -(-len(x) // MIXTURE_SAMPLES))
    fit_x, fit_start = x[::step], start[::step]
    if not (np.bincount(fit_start, minlength=k) > 0).all():
        fit_x, fit_start = x, start
    resp = np.eye(k)[fit_start]
    previous = -np.inf
    for _ in range(MIXTURE_ITERATIONS):
        # M step: shares, means and floored variances from the responsibilities.
        nk = resp.sum(0) + 1e-12
        weights = nk / nk.sum()
        means = resp.T @ fit_x / nk[:, None]
        variances = np.maximum(resp.T @ (fit_x * fit_x) / nk[:, None] - means * means,
                               VARIANCE_FLOOR)
        # E step: responsibilities, and the mean log-likelihood to stop on.
        logp = log_joint(fit_x, means, weights, variances)
        top = logp.max(1, keepdims=True)
        resp = np.exp(logp - top)
        total = resp.sum(1, keepdims=True)
        resp /= total
        likelihood = float((np.log(total) + top).mean())
        if likelihood - previous < MIXTURE_TOLERANCE:
            break
        previous = likelihood
    # Back to every feature: the constant ones keep their value and the floor variance.
    full_means = np.tile(samples[0].astype(np.float32), (k, 1))
    full_means[:, active] = means
    full_variances = np.full((k, f), VARIANCE_FLOOR, np.float32)
    full_variances[:, active] = variances
    labels = log_joint(x, means, weights, variances).argmax(1)
    return labels, full_means, weights, full_variances


def posterior_fn(centres: np.ndarray, sizes: np.ndarray, variances: np.ndarray,
                 weights: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """Gaussian-mixture posterior of each theme for a coarse feature stack.

    Parameters
    ----------
    centres : (K, F) ndarray
        Theme means in weighted feature space.
    sizes : (K,) ndarray
        Mixture weights.
    variances : (K, F) ndarray
        Per-theme, per-feature variances (all equal for the k-means spread).
    weights : (F,) ndarray
        Feature weights applied to the raw features first.

    Returns
    -------
    probs : callable
        ``(h, w, F) float32 -> (h, w, K) float32`` posteriors.
    """
    k, f = centres.shape
    centres = centres.astype(np.float32)

    def probs(feats: np.ndarray) -> np.ndarray:
        h, w, _ = feats.shape
        logit = log_joint(feats.reshape(-1, f) * weights, centres, sizes, variances)
        logit -= logit.max(1, keepdims=True)
        p = np.exp(logit)
        p /= p.sum(1, keepdims=True)
        return p.reshape(h, w, k).astype(np.float32)

    return probs
