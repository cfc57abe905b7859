"""Options of supervised classification (:func:`core.classify.supervised.train_classifier`).

Kept apart from the classifier so that the model file (:mod:`core.classify.model_file`)
can read and write them without importing the classifier.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from terratheme.core.classify.features import FeatureOptions
from terratheme.core.classify.regularise import Regularisation, RegulariseOptions
from terratheme.core.errors import TerrathemeError

#: the smallest per-class cap on training samples (see SupervisedOptions.samples_per_pair)
MIN_SAMPLES_PER_CLASS = 2000
#: adapt=None: test-time adaptation for models trained on masks of fewer photos than this
ADAPT_MAX_PAIRS = 10


@dataclass(frozen=True)
class SupervisedOptions:
    """Options of :func:`train_classifier` (defaults' measurements: docs/decisions.md).

    Attributes
    ----------
    ignore_classes : tuple of int
        Mask values treated as unlabelled (besides 0).
    samples_per_pair : int
        Per-class samples grow with the pairs (:meth:`samples_per_class`).
    balance : bool
        Equal class priors whatever the sample counts.
    prior_power : float or None
        Votes weighted by ``(estimated share / training share) ** prior_power``; 0 off,
        None ``SCRIBBLE_PRIOR_POWER`` for scribbles.
    grow_colour : float or None
        Lab difference under which scribbles grow by one ring of coarse pixels; 0 off,
        None ``GROW_COLOUR`` for scribbles.
    adapt : bool or None
        Test-time adaptation; None: on below ``ADAPT_MAX_PAIRS`` mask photos, off for
        scribbles (:meth:`resolved`).
    """

    features: FeatureOptions = field(default_factory=lambda: FeatureOptions(
        hessian=True, ridge_sigmas=(1.0, 2.0, 4.0), structure=True))
    regularisation: RegulariseOptions = field(
        default_factory=lambda: RegulariseOptions(method=Regularisation.EDGE))
    ignore_classes: tuple[int, ...] = ()
    n_trees: int = 50
    max_depth: int = 12
    min_samples: int = 4
    max_samples_per_class: int = 15000
    samples_per_pair: int = 400
    balance: bool = True
    seed: int = 0
    tile: int = 2048
    prior_power: float | None = None
    grow_colour: float | None = None
    adapt: bool | None = None

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
