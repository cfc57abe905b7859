"""Class-prior correction of a forest trained from scribbles (transductive step).

A user paints about as much of every class, so a forest of scribbles over-predicts
rare classes. The photo's class shares ``pi_k`` are estimated by "classify and count"
(Forman 2008) and the posteriors multiplied by ``(pi_k / t_k) ** power`` (``t_k`` the
training priors; Saerens, Latinne & Decaestecker 2002, eq. 2.4), then renormalised.
A power under 1 keeps a thin class of small area: vote shares are not calibrated.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from terratheme.core.classify.features import FeatureOptions
from terratheme.core.classify.samples import looks_like_scribbles
from terratheme.core.classify.tiled import iter_tile_features, sampling_stride, strided_pixels
from terratheme.core.errors import TerrathemeError

#: default correction for scribbles (docs/decisions.md)
SCRIBBLE_PRIOR_POWER = 0.75
#: coarse pixels of the photo the priors are estimated on (strided, at most)
PRIOR_SAMPLES = 200_000


def prior_power_for(pairs: Sequence[tuple[np.ndarray, np.ndarray]], power: float | None,
                    ignore_classes: Sequence[int] = ()) -> float:
    """``power`` if given, else ``SCRIBBLE_PRIOR_POWER`` for scribbles and 0 for full
    label masks (they hold their photos' true class shares already)."""
    if power is not None:
        return float(power)
    return SCRIBBLE_PRIOR_POWER if looks_like_scribbles(pairs, ignore_classes) else 0.0


def predicted_shares(probs: np.ndarray) -> np.ndarray:
    """"Classify and count": the share (C,) of the samples ``probs`` (n, C) whose most
    probable class is each class (uniform when n = 0)."""
    c = probs.shape[1]
    if len(probs) == 0:
        return np.full(c, 1.0 / c)
    return np.bincount(np.argmax(probs, axis=1), minlength=c) / len(probs)


def prior_weights(shares: np.ndarray, train_priors: np.ndarray, power: float) -> np.ndarray:
    """Class weights ``(pi_k / t_k) ** power`` (Saerens et al. 2002, eq. 2.4) scaled to max 1,
    from the photo's shares ``pi`` and the training priors ``t`` (both (C,))."""
    # A class the photo seems not to have keeps a small weight (it was scribbled).
    ratio = np.maximum(np.asarray(shares, np.float64), 1e-3) / np.asarray(train_priors, float)
    weights = ratio ** float(power)
    return weights / weights.max()


def photo_probabilities(
    rgb: np.ndarray, valid: np.ndarray | None, probability_fn: Callable[[np.ndarray], np.ndarray],
    features: FeatureOptions, tile: int, max_samples: int = PRIOR_SAMPLES,
) -> np.ndarray:
    """Posteriors (n, C) float32 of at most ``max_samples`` coarse pixels of a photo with
    data (``valid``; :func:`core.classify.tiled.strided_pixels`), ``probability_fn``
    applied tile by tile."""
    scale = features.scale
    h, w = rgb.shape[:2]
    stride = sampling_stride(h, w, scale, max_samples)
    out = []
    for win, _lab, feats in iter_tile_features(rgb, features, tile, features.halo):
        part = None if valid is None else valid[win.y : win.y1, win.x : win.x1]
        iy, ix, _, _ = strided_pixels(win, scale, stride, part)
        probs = probability_fn(np.ascontiguousarray(feats[iy, ix][None]))
        out.append(probs.reshape(-1, probs.shape[-1]))
    return np.concatenate(out).astype(np.float32)


def kept_weights(weights: Mapping[int, float], classes: Sequence[int]) -> tuple[float, ...] | None:
    """Given prior weights (class value -> weight) in ``classes`` order, None if one is missing.

    Keeps round 1's correction when a classifier is retrained on correction strokes
    (painted where the result is wrong, so they say nothing of the class shares).
    A weight that is not a finite number > 0 is a ``TerrathemeError``.
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
