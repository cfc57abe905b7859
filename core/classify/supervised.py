"""Supervised classes: Extra-Trees (:mod:`core.classify.extra_trees`) on the features.

Training data are ``(photo, mask)`` pairs (0 unlabelled): scribbles or full label masks.
Samples are capped per class; scribbles also get a prior correction (:mod:`.prior`) and
strokes grown by colour; a model of other photos adapts to each photo (:mod:`.adapt`).
Confidence is the winning class's share of the trees' soft votes.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from terratheme.core.classify.adapt import predict_adapted
from terratheme.core.classify.extra_trees import (
    ExtraTreesForest,
    build_forest,
    forest_probabilities,
)
from terratheme.core.classify.model_file import ModelParts, read_model, write_model
from terratheme.core.classify.photo import PreparedPhoto, prepare_photo
from terratheme.core.classify.prior import (
    kept_weights,
    photo_probabilities,
    predicted_shares,
    prior_power_for,
    prior_weights,
)
from terratheme.core.classify.result import Classification, merged_class_names
from terratheme.core.classify.samples import (
    GROW_COLOUR,
    check_class_image,
    coarse_mask,
    grow_labels,
    looks_like_scribbles,
)
from terratheme.core.classify.supervised_options import SupervisedOptions
from terratheme.core.classify.tiled import iter_tile_features, predict_tiled
from terratheme.core.classify.training_cache import (
    cached_model,
    cached_samples,
    model_key,
    sample_key,
)
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.disk_cache import DiskCache


def _pair_samples(photo, mask, index, classes, options, grow=0.0):
    """Labelled coarse feature vectors of one pair -> (features (n, F), labels (n,)).

    ``grow`` > 0 adds the coarse pixels :func:`grow_labels` finds next to the labels.
    """
    rgb, valid = prepare_photo(photo)
    m = check_class_image(mask, f"label mask {index}", rgb.shape[:2])
    if valid is not None:
        m = np.where(valid, m, 0).astype(np.uint8)
    fo, scale = options.features, options.features.scale
    target = coarse_mask(m, scale, classes)
    feats_out, labels_out = [], []
    for win, lab, feats in iter_tile_features(rgb, fo, options.tile, fo.halo):
        # Labelled coarse pixels of this tile's core.
        cy0, cx0 = win.y // scale, win.x // scale
        cy1, cx1 = -(-win.y1 // scale), -(-win.x1 // scale)
        lab_core = target[cy0:cy1, cx0:cx1]
        if not lab_core.any():
            continue
        oy, ox = cy0 - win.ry // scale, cx0 - win.rx // scale
        if grow > 0:
            # Grow over the whole window (its halo holds the core's neighbours), keep the core.
            grown = grow_labels(target[win.ry // scale : -(-win.ry1 // scale),
                                       win.rx // scale : -(-win.rx1 // scale)], lab, grow)
            lab_core = grown[oy : oy + lab_core.shape[0], ox : ox + lab_core.shape[1]]
        core = feats[oy : oy + lab_core.shape[0], ox : ox + lab_core.shape[1]]
        sel = lab_core > 0
        feats_out.append(core[sel])
        labels_out.append(lab_core[sel])
    if not feats_out:
        return np.zeros((0, fo.n_features), np.float32), np.zeros(0, np.uint8)
    return np.concatenate(feats_out), np.concatenate(labels_out)


def _mask_classes(pairs, ignore) -> list[int]:
    found: set[int] = set()
    for _photo, mask in pairs:
        found.update(int(v) for v in np.unique(np.asarray(mask)))
    return sorted(found - {0} - set(ignore))


def _training_plan(pairs, options) -> tuple[list[int], float]:
    """Check the pairs -> (the classes to sample, the label growing threshold)."""
    if len(pairs) == 0:
        raise TerrathemeError("no training data: give at least one photo with a label mask")
    for i, (photo, mask) in enumerate(pairs):
        rgb = photo.rgb if isinstance(photo, PreparedPhoto) else np.asarray(photo)
        check_class_image(mask, f"label mask {i}", rgb.shape[:2])
    classes = _mask_classes(pairs, options.ignore_classes)
    if not classes:
        raise TerrathemeError(
            "the label masks name no class (all pixels 0 or ignored): paint at least one class"
        )
    grow = options.grow_colour
    if grow is None:
        grow = GROW_COLOUR if looks_like_scribbles(pairs, options.ignore_classes) else 0.0
    return classes, grow


def _sample_keys(pairs, classes, grow, options) -> list[str]:
    return [sample_key(photo, mask, classes, options.features, options.tile, grow)
            for photo, mask in pairs]


def collect_samples(
    pairs: Sequence[tuple[np.ndarray, np.ndarray]], options: SupervisedOptions,
    cache: DiskCache | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Training features (n, F) float32 and class values (n,) int32 of photo/mask pairs,
    capped per class; ``cache`` keeps each pair's samples by content (same result)."""
    classes, grow = _training_plan(pairs, options)
    keys = None if cache is None else _sample_keys(pairs, classes, grow, options)
    return _capped_samples(pairs, options, classes, grow, cache, keys)


def _capped_samples(pairs, options, classes, grow, cache, keys):
    """:func:`collect_samples` once planned (``keys``: the pairs' sample keys, with ``cache``)."""
    rng = np.random.default_rng(options.seed)
    cap = options.samples_per_class(len(pairs))
    per_class: dict[int, list[np.ndarray]] = {k: [] for k in classes}
    for i, (photo, mask) in enumerate(pairs):
        if cache is None:
            feats, labels = _pair_samples(photo, mask, i, classes, options, grow)
        else:
            feats, labels = cached_samples(
                cache, keys[i], options.features.n_features, classes,
                lambda photo=photo, mask=mask, i=i: _pair_samples(photo, mask, i, classes,
                                                                  options, grow))
        for k in classes:
            sel = feats[labels == k]
            # Cap each pair's share so one big photo does not crowd out the others.
            if len(sel) > cap:
                sel = sel[rng.choice(len(sel), cap, replace=False)]
            per_class[k].append(sel)
    xs, ys = [], []
    for k in classes:
        sel = np.concatenate(per_class[k])
        if len(sel) > cap:
            sel = sel[rng.choice(len(sel), cap, replace=False)]
        xs.append(sel)
        ys.append(np.full(len(sel), k, np.int32))
    x, y = np.concatenate(xs).astype(np.float32), np.concatenate(ys)
    if len(y) == 0:
        raise TerrathemeError("the labelled pixels are all transparent: nothing to train on")
    return x, y


class Classifier:
    """A trained Extra-Trees forest and its options (made by :func:`train_classifier`)."""

    def __init__(self, forest: ExtraTreesForest | None, classes: Sequence[int],
                 options: SupervisedOptions,
                 class_weights: Sequence[float] | None = None,
                 class_names: Mapping[int, str] | None = None) -> None:
        self.forest = forest
        self.classes = tuple(int(c) for c in classes)
        self.options = options
        #: name of each class value (e.g. a shipped model's "water"), or None
        self.class_names = None if class_names is None else {
            int(k): str(v) for k, v in class_names.items() if int(k) in self.classes}
        #: per-class vote weights (prior correction), ``classes`` order; None = all 1
        self.class_weights = None if class_weights is None else tuple(
            float(v) for v in class_weights)
        if self.class_weights is not None and len(self.class_weights) != len(self.classes):
            raise TerrathemeError(f"{len(self.class_weights)} class weights for "
                                  f"{len(self.classes)} classes")

    @property
    def context_pixels(self) -> int:
        """Photo pixels of context a label needs on each side (pieces read so from multiples
        of the feature scale get the whole photo's labels, up to EDGE's ~1e-6 rounding)."""
        fo, reg = self.options.features, self.options.regularisation
        return (fo.halo + reg.halo + 1) * fo.scale

    def probabilities(self, feats: np.ndarray) -> np.ndarray:
        """Vote shares (h, w, C) float32, channels in ``self.classes`` order, of a coarse
        feature stack (h, w, F) float32."""
        if self.forest is None:
            return np.ones((*feats.shape[:2], 1), np.float32)
        # class_weights: the prior correction (core.classify.prior).
        return forest_probabilities(self.forest, feats, self.classes, self.class_weights)

    def predict(self, photo: np.ndarray,
                progress: Callable[[int, int], None] | None = None) -> Classification:
        """The training masks' class values of a (H, W, 3|4) uint8/uint16 photo's pixels;
        ``progress(done, total)`` over the tiles."""
        rgb, valid = prepare_photo(photo)
        opts = self.options
        if self.forest is not None and opts.adapt:
            return predict_adapted(rgb, valid, self.probabilities, self.classes, opts.features,
                                   opts.regularisation, opts, opts.tile, progress)
        return predict_tiled(rgb, valid, self.probabilities, self.classes, opts.features,
                             opts.regularisation, opts.tile, progress)

    def parts(self) -> ModelParts:
        """What a model file of this model holds (:mod:`core.classify.model_file`)."""
        return ModelParts(self.forest, tuple(self.classes), self.options, self.class_weights,
                          self.class_names)

    def save(self, path: str | os.PathLike) -> None:
        """Write the model to a file (atomic); see :mod:`core.classify.model_file`."""
        write_model(path, self.parts())

    @classmethod
    def load(cls, path: str | os.PathLike) -> Classifier:
        """Read a model written by :meth:`save`."""
        parts = read_model(path)
        return cls(parts.forest, parts.classes, parts.options, parts.class_weights,
                   parts.class_names)

    def name_classes(self, names: Mapping[int, str]) -> None:
        """Name the classes after a legend, over the model's own names (others skipped)."""
        self.class_names = merged_class_names(self.classes, self.class_names, names)


def train_classifier(
    pairs_or_scribbles: Sequence[tuple[np.ndarray, np.ndarray]],
    options: SupervisedOptions | None = None,
    *,
    class_weights: Mapping[int, float] | None = None,
    cache: DiskCache | None = None,
) -> Classifier:
    """Train a classifier from (photo (H, W, 3|4), mask (H, W) integer, 0 unlabelled) pairs.

    ``class_weights`` (class value -> weight) replace the estimated prior when they cover
    every class; ``cache`` keeps samples and the model by content.
    """
    opts = options or SupervisedOptions()
    scribbles = looks_like_scribbles(pairs_or_scribbles, opts.ignore_classes)
    # Adapt to each photo when trained on a few other photos (scribbles lie on the photo).
    opts = opts.resolved(len(pairs_or_scribbles), scribbles)
    classes, grow = _training_plan(pairs_or_scribbles, opts)
    if cache is None:
        return _fit(pairs_or_scribbles, opts, classes, grow, None, None, class_weights)
    keys = _sample_keys(pairs_or_scribbles, classes, grow, opts)
    parts = cached_model(
        cache, model_key(keys, classes, opts, class_weights), opts,
        lambda: _fit(pairs_or_scribbles, opts, classes, grow, cache, keys,
                     class_weights).parts())
    return Classifier(parts.forest, parts.classes, parts.options, parts.class_weights)


def _fit(pairs, opts, classes, grow, cache, keys, class_weights) -> Classifier:
    """:func:`train_classifier` once planned: samples, forest, prior weights."""
    x, y = _capped_samples(pairs, opts, classes, grow, cache, keys)
    classes, counts = np.unique(y, return_counts=True)
    forest = build_forest(x, y, opts) if len(classes) > 1 else None
    model = Classifier(forest, classes, opts)
    # Weights given for every class (kept from a first round of strokes): no estimate.
    kept = None if class_weights is None else kept_weights(class_weights, model.classes)
    if forest is not None and kept is not None:
        model.class_weights = kept
        return model
    power = prior_power_for(pairs, opts.prior_power, opts.ignore_classes)
    if forest is not None and power > 0:
        # Class shares of the scribbled photo from the forest's votes on it, as weights.
        rgb, valid = prepare_photo(pairs[0][0])
        probs = photo_probabilities(rgb, valid, model.probabilities, opts.features, opts.tile)
        train = np.full(len(classes), 1.0 / len(classes)) if opts.balance else counts / len(y)
        weights = prior_weights(predicted_shares(probs), train, power)
        model.class_weights = tuple(float(v) for v in weights)
    return model
