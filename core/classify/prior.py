"""Class-prior correction of a forest trained from scribbles (transductive step).

A user paints about the same amount of every class, so a forest trained on
scribbles believes every class is equally common, and (with
``SupervisedOptions.balance``) is even told so. On the photo itself, roads
or buildings may cover 5% and bare land 60%: the forest then over-predicts
the rare classes, which costs mean IoU on the common ones.

Scribbles are painted on the photo that is classified, so the photo's own
class shares ``pi_k`` can be estimated from the forest's outputs on it:
"classify and count" (Forman 2008), the share of the photo's coarse pixels
whose arg-max class is ``k``. The posteriors are then adjusted to these
priors as in Saerens, Latinne & Decaestecker (2002, eq. 2.4): multiplied by
the class weights ``(pi_k / t_k) ** power`` (``t_k``: the training priors)
and renormalised. ``power = 1`` is the paper's full adjustment. The
default for scribbles is ``0.75``, chosen on tuning photos that are not in
the benchmark's evaluation set (Dubai parts 001-003, 18 photos, simulated
scribbles, with the EDGE regularisation): mean mIoU / Dubai-pooled mIoU
0.590 / 0.677, 0.591 / 0.680, 0.587 / 0.681 for powers 0.5 / 0.75 / 1.
The full adjustment can erase a thin class whose area is small (a road in
heavy shadow, tests/test_classify_stability.py), and the forest's vote
shares are not calibrated posteriors to begin with. The paper's EM estimate of
``pi`` (eq. 2.9-2.10) scored the same within noise (0.559 at power 0.5,
0.554 at 0.75) but drifts when a forest trained on a handful of samples is
unsure (three flat stripes with one stroke each got weights 1 : 0.57 : 0.82),
so the robust count is used.

Across photos (a model trained on full label masks of other photos, applied
to a new one) the class shares of the new photo are unknown as well;
:func:`em_shares` is the paper's EM estimate for that case
(``SupervisedOptions.target_prior``). Measured on the issue-17 protocol
(bench_classify.py part ``one_per_tile``) it lowers mean mIoU, so it is off
by default: the forest's shares are over-confident, and the reweighting
erases rare classes (roads, vegetation) that mean IoU counts as much as land.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from terratheme.core.classify.features import FeatureOptions
from terratheme.core.classify.samples import looks_like_scribbles
from terratheme.core.classify.tiled import iter_tile_features, strided_core
from terratheme.core.errors import TerrathemeError

#: default correction for scribbles (benchmark: benchmarks/results/classify.json,
#: scribbles "rf-default" vs "rf-noprior")
SCRIBBLE_PRIOR_POWER = 0.75
#: coarse pixels of the photo the priors are estimated on (strided, at most)
PRIOR_SAMPLES = 200_000


def prior_power_for(pairs: Sequence[tuple[np.ndarray, np.ndarray]], power: float | None,
                    ignore_classes: Sequence[int] = ()) -> float:
    """The correction to apply: ``power`` if given, else ``SCRIBBLE_PRIOR_POWER`` for scribbles.

    Scribbles are one ``(photo, mask)`` pair with under ``samples.SCRIBBLE_SHARE`` of
    the mask labelled (non-zero, not ignored); full label masks get 0 (off):
    they hold their photos' true class shares already.
    """
    if power is not None:
        return float(power)
    return SCRIBBLE_PRIOR_POWER if looks_like_scribbles(pairs, ignore_classes) else 0.0


def predicted_shares(probs: np.ndarray) -> np.ndarray:
    """Share of samples whose most probable class is each class ("classify and count").

    Parameters
    ----------
    probs : (n, C) float ndarray
        Classifier posteriors of n samples of the photo.

    Returns
    -------
    shares : (C,) float64 ndarray, sums to 1 (uniform when n = 0)
    """
    c = probs.shape[1]
    if len(probs) == 0:
        return np.full(c, 1.0 / c)
    return np.bincount(np.argmax(probs, axis=1), minlength=c) / len(probs)


def em_shares(probs: np.ndarray, train_priors: np.ndarray, iterations: int = 100,
              tol: float = 1e-6) -> np.ndarray:
    """Class shares of a new photo by EM (Saerens, Latinne & Decaestecker 2002, eq. 2.9-2.10).

    Each step adjusts every sample's posteriors to the current shares
    ``pi`` (eq. 2.9: ``p_k * pi_k / t_k``, renormalised) and takes their
    mean as the new shares (eq. 2.10), from ``pi = t``.

    Parameters
    ----------
    probs : (n, C) float ndarray
        Posteriors of n samples under the training priors.
    train_priors : (C,) float ndarray
        Priors ``t`` the classifier was trained with (all > 0).
    iterations : int
        Most EM steps.
    tol : float
        Stop when no share moves by more than this.

    Returns
    -------
    shares : (C,) float64 ndarray, sums to 1 (``train_priors`` when n = 0)
    """
    t = np.asarray(train_priors, np.float64)
    t = t / t.sum()
    p = np.asarray(probs, np.float64)
    pi = t.copy()
    if len(p) == 0:
        return pi
    for _ in range(iterations):
        # E step: posteriors adjusted to the current shares (eq. 2.9).
        q = p * (pi / t)[None, :]
        q /= np.maximum(q.sum(1, keepdims=True), 1e-300)
        # M step: the new shares are the adjusted posteriors' mean (eq. 2.10).
        new = q.mean(0)
        done = np.abs(new - pi).max() <= tol
        pi = new
        if done:
            break
    return pi


def prior_weights(shares: np.ndarray, train_priors: np.ndarray, power: float) -> np.ndarray:
    """Class weights ``(pi_k / t_k) ** power`` (Saerens et al. 2002, eq. 2.4), max 1.

    Parameters
    ----------
    shares : (C,) float ndarray
        Estimated class shares ``pi`` of the photo.
    train_priors : (C,) float ndarray
        Class priors ``t`` the classifier was trained with.
    power : float
        0..1; 0 gives all ones.

    Returns
    -------
    weights : (C,) float64 ndarray in (0, 1]
    """
    # A class the photo seems not to have keeps a small weight (it was scribbled).
    ratio = np.maximum(np.asarray(shares, np.float64), 1e-3) / np.asarray(train_priors, float)
    weights = ratio ** float(power)
    return weights / weights.max()


def photo_probabilities(
    rgb: np.ndarray, valid: np.ndarray | None, probability_fn: Callable[[np.ndarray], np.ndarray],
    features: FeatureOptions, tile: int, stats: np.ndarray | None = None,
    max_samples: int = PRIOR_SAMPLES,
) -> np.ndarray:
    """Posteriors of (at most ``max_samples``) coarse pixels of a photo, tile by tile.

    Parameters
    ----------
    rgb : (H, W, 3) uint8 ndarray
    valid : (H, W) bool ndarray or None
    probability_fn : callable, (h, w, F) float32 -> (h, w, C) float32
    features : FeatureOptions
    tile : int
    stats : (2, 3) float32 ndarray, optional (colour normalisation)

    Returns
    -------
    probs : (n, C) float32 ndarray
    """
    scale = features.scale
    h, w = rgb.shape[:2]
    n_coarse = (-(-h // scale)) * (-(-w // scale))
    stride = max(1, int(np.sqrt(n_coarse / max_samples)))
    out = []
    for win, _lab, feats in iter_tile_features(rgb, features, tile, features.halo, stats):
        # This tile's core, on a global grid of every stride-th coarse row/column.
        core, rows, cols = strided_core(feats, win, scale, stride)
        if core.size == 0:
            continue
        probs = probability_fn(np.ascontiguousarray(core))
        if valid is not None:
            # Keep coarse pixels whose top-left photo pixel has data.
            probs = probs[valid[np.ix_(np.minimum(rows * scale, h - 1),
                                       np.minimum(cols * scale, w - 1))]]
        out.append(probs.reshape(-1, probs.shape[-1]))
    return np.concatenate(out).astype(np.float32)


def kept_weights(weights: Mapping[int, float], classes: Sequence[int]) -> tuple[float, ...] | None:
    """Given prior weights in ``classes`` order, or None if they miss a class.

    Used to keep the correction estimated from a first round of blind strokes
    when the classifier is retrained on correction strokes (painted where the
    result is wrong, so their placement says nothing about the class shares;
    benchmarks/classify_corrections.py: mean mIoU 0.598 kept vs 0.557 re-estimated).

    Parameters
    ----------
    weights : mapping of class value -> weight
        Every weight finite and > 0; classes not in ``classes`` are ignored.
    classes : sequence of int
        The trained classes, in the classifier's order.

    Returns
    -------
    tuple of float, one per class, or None when a class has no weight

    Raises
    ------
    TerrathemeError
        A weight that is negative, zero, NaN or infinite.
    """
    for value, w in weights.items():
        try:
            ok = bool(np.isfinite(float(w)) and float(w) > 0)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise TerrathemeError(
                f"class weight {w!r} of class {value} must be a finite number > 0")
    if any(int(c) not in weights for c in classes):
        return None
    return tuple(float(weights[int(c)]) for c in classes)
