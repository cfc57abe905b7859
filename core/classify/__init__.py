"""Orthophoto classification into themes (DESIGN.md section 4).

Public API (stable; used by ``terratheme classify`` and ``convert``):

* :func:`classify_unsupervised` -- k-means themes, K chosen from the data;
* :func:`train_classifier` -> :class:`Classifier` (``predict``, ``save``,
  ``Classifier.load``) -- random forest from scribbles or label masks;
* :class:`Classification` -- ``labels`` (H, W) uint8 + ``confidence`` (H, W)
  float32 in [0, 1].

Modules: ``photo`` (input checks), ``features`` (Lab + texture on a downscaled
photo), ``tiled`` (tile-by-tile prediction with overlap), ``regularise``
(smoothing / superpixels), ``unsupervised``, ``supervised``, ``model_file``.
"""

from core.classify.features import FeatureOptions, FeatureSet, Normalise
from core.classify.regularise import Regularisation, RegulariseOptions
from core.classify.result import Classification
from core.classify.supervised import Classifier, SupervisedOptions, train_classifier
from core.classify.unsupervised import UnsupervisedOptions, classify_unsupervised

__all__ = [
    "Classification",
    "Classifier",
    "FeatureOptions",
    "FeatureSet",
    "Normalise",
    "Regularisation",
    "RegulariseOptions",
    "SupervisedOptions",
    "UnsupervisedOptions",
    "classify_unsupervised",
    "train_classifier",
]
