"""Options of supervised classification (:func:`core.classify.supervised.train_classifier`).

Kept apart from the classifier so that the model file (:mod:`core.classify.model_file`)
can read and write them without importing the classifier.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from terratheme.core.classify.features import FeatureOptions
from terratheme.core.classify.forest import ForestKind
from terratheme.core.classify.regularise import Regularisation, RegulariseOptions
from terratheme.core.errors import TerrathemeError

#: the smallest per-class cap on training samples (see SupervisedOptions.samples_per_pair)
MIN_SAMPLES_PER_CLASS = 2000
#: adapt=None: test-time adaptation for models trained on masks of fewer photos than this
ADAPT_MAX_PAIRS = 10


@dataclass(frozen=True)
class SupervisedOptions:
    """Options of :func:`train_classifier`.

    Attributes
    ----------
    features : FeatureOptions
        Default: the DEFAULT set with Hessian eigenvalues (+0.009 mean scribble mIoU on
        the tuning photos), fine ridges at 1, 2, 4 px (:mod:`core.classify.ridges`) and
        the structure features (:mod:`core.classify.texture`: one photo per tile mean
        tile mIoU 0.417 -> 0.425).
    regularisation : RegulariseOptions
        Default: edge-aware, confidence-weighted averaging (``Regularisation.EDGE``,
        :func:`core.classify.regularise.edge_aware_probabilities`); on the
        scribble benchmark it beat the Gaussian smoothing by +0.014 mean mIoU
        (tuning photos, Dubai parts 001-003) at the same speed.
    ignore_classes : tuple of int
        Mask values treated as unlabelled (besides 0).
    forest : ForestKind
        Default Extra-Trees (:mod:`core.classify.extra_trees`); RANDOM_FOREST is
        OpenCV's forest of earlier versions.
    n_trees : int
        Trees in the forest.
    max_depth : int
        Depth limit of each tree.
    min_samples : int
        Smallest node that is still split.
    active_vars : int
        RANDOM_FOREST: features tried per split (0: ``sqrt(F)``; Extra-Trees
        always tries ``sqrt(F)``).
    max_samples_per_class : int
        Most training samples of one class (over all pairs).
    samples_per_pair : int
        Training samples per class grow with the pairs: at most
        ``samples_per_pair * len(pairs)``, at least ``MIN_SAMPLES_PER_CLASS``
        (2000), at most ``max_samples_per_class``
        (:meth:`samples_per_class`). Five photos of other areas train best
        on few samples (one-photo-per-tile protocol, exploration runs at coarse
        level: mean tile mIoU 0.390 / 0.396 / 0.400 with 4000 / 2000 / 1000 per
        class, and the forest fits 2.4x faster at 2000 than at 4000), 54 photos
        on many (0.452 with 8000, 0.441 with 2000); scribbles give a few hundred.
    balance : bool
        Equal class priors whatever the sample counts.
    seed : int
        Sampling and forest RNG seed.
    tile : int
        Tile core size in photo pixels.
    prior_power : float or None
        Class-prior correction (:mod:`core.classify.prior`): the votes are
        weighted by ``(estimated share / training share) ** prior_power``.
        0 = off; None = ``prior.SCRIBBLE_PRIOR_POWER`` when training from
        scribbles (one photo, under ``samples.SCRIBBLE_SHARE`` of its pixels
        labelled), else off.
    grow_colour : float or None
        Scribble samples grown by one ring of coarse pixels of the stroke's
        colour (:func:`core.classify.samples.grow_labels`, Lab difference under
        this). 0 = off; None = ``samples.GROW_COLOUR`` for scribbles, else off.
    adapt : bool or None
        Test-time adaptation (:mod:`core.classify.adapt`): each photo is
        classified, its surest pixels relearned by a small forest, and
        classified again with both. None = on for a model trained on label
        masks of fewer than ``ADAPT_MAX_PAIRS`` (10) photos, off for more and
        for scribbles (they lie on the photo already); resolved by
        :func:`train_classifier`. bench_classify.py: trained on one photo per
        other Dubai tile (part ``one_per_tile``, 3 draws of 5 photos) mean tile
        mIoU 0.414 -> 0.417 and mean mIoU per photo 0.358 -> 0.392 (a class the
        photo barely shows is no longer scattered over it); trained on every
        photo of the other tiles (part ``across_tiles``, 45 photos) pooled mIoU
        0.514 -> 0.509, so off there; 0.7x the prediction speed.
    target_prior_power : float
        Class shares of each classified photo re-estimated by EM
        (:func:`core.classify.prior.em_shares`) and the votes reweighted by
        ``(share / training share) ** target_prior_power``; 0 = off (default:
        at 1, mean tile mIoU 0.414 -> 0.323 in part ``one_per_tile``). Needs
        ``balance``.
    """

    features: FeatureOptions = field(default_factory=lambda: FeatureOptions(
        hessian=True, ridge_sigmas=(1.0, 2.0, 4.0), structure=True))
    regularisation: RegulariseOptions = field(
        default_factory=lambda: RegulariseOptions(method=Regularisation.EDGE))
    ignore_classes: tuple[int, ...] = ()
    forest: ForestKind = ForestKind.EXTRA_TREES
    n_trees: int = 50
    max_depth: int = 12
    min_samples: int = 4
    active_vars: int = 0
    max_samples_per_class: int = 15000
    samples_per_pair: int = 400
    balance: bool = True
    seed: int = 0
    tile: int = 2048
    prior_power: float | None = None
    grow_colour: float | None = None
    adapt: bool | None = None
    target_prior_power: float = 0.0

    def __post_init__(self) -> None:
        if self.prior_power is not None and not 0.0 <= self.prior_power <= 1.0:
            raise TerrathemeError(f"prior_power must be in 0..1 or None, not {self.prior_power}")
        if (self.n_trees < 1 or self.max_depth < 1 or self.max_samples_per_class < 1
                or self.samples_per_pair < 1):
            raise TerrathemeError(
                "n_trees, max_depth, max_samples_per_class and samples_per_pair must be at "
                f"least 1 (got {self.n_trees}, {self.max_depth}, {self.max_samples_per_class}, "
                f"{self.samples_per_pair})"
            )
        if self.grow_colour is not None and self.grow_colour < 0:
            raise TerrathemeError(f"grow_colour must be >= 0 or None, not {self.grow_colour}")
        if not 0.0 <= self.target_prior_power <= 1.0:
            raise TerrathemeError(
                f"target_prior_power must be in 0..1, not {self.target_prior_power}")
        if self.target_prior_power > 0 and not self.balance:
            raise TerrathemeError("target_prior_power needs balance (uniform training priors)")
        if self.tile < 16:
            raise TerrathemeError(f"tile must be at least 16 pixels, not {self.tile}")

    def samples_per_class(self, n_pairs: int) -> int:
        """The cap on training samples of one class for ``n_pairs`` training pairs."""
        return min(self.max_samples_per_class,
                   max(MIN_SAMPLES_PER_CLASS, self.samples_per_pair * n_pairs))

    def resolved(self, n_pairs: int, scribbles: bool) -> SupervisedOptions:
        """These options with ``adapt`` decided for a training set (see ``adapt``)."""
        if self.adapt is not None:
            return self
        return replace(self, adapt=not scribbles and n_pairs < ADAPT_MAX_PAIRS)

    def with_positions(self, on: bool = True) -> SupervisedOptions:
        """These options with the position features (``FeatureOptions.position``) ``on``."""
        return replace(self, features=replace(self.features, position=on))
