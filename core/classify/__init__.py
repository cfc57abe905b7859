"""Orthophoto classification into themes (design.md §3).

Public API (used by ``terratheme classify`` and ``convert``):

* :func:`classify_unsupervised` -- k-means themes, K chosen from the data;
* :func:`fit_unsupervised` -> :class:`UnsupervisedModel` (``predict``) -- the
  same themes fitted on a sample (or pieces of a big photo), applied per tile;
* :func:`train_classifier` -> :class:`Classifier` (``predict``, ``save``,
  ``Classifier.load``) -- Extra-Trees from scribbles or label masks;
* :class:`Classification` -- ``labels`` (H, W) uint8 + ``confidence`` (H, W)
  float32 in [0, 1];
* :func:`load_model` / :func:`resolve_model` / :func:`shipped_models` -- a
  classifier file or a shipped model by name (``aerial``), with class names.
"""

from terratheme.core.classify.features import FeatureOptions, FeatureSet
from terratheme.core.classify.regularise import Regularisation, RegulariseOptions
from terratheme.core.classify.result import Classification
from terratheme.core.classify.shipped import load_model, resolve_model, shipped_models
from terratheme.core.classify.supervised import Classifier, train_classifier
from terratheme.core.classify.supervised_options import SupervisedOptions
from terratheme.core.classify.unsupervised import UnsupervisedOptions
from terratheme.core.classify.unsupervised_model import (
    UnsupervisedModel,
    classify_unsupervised,
    fit_unsupervised,
)

__all__ = [
    "Classification",
    "Classifier",
    "FeatureOptions",
    "FeatureSet",
    "Regularisation",
    "RegulariseOptions",
    "SupervisedOptions",
    "UnsupervisedModel",
    "UnsupervisedOptions",
    "classify_unsupervised",
    "fit_unsupervised",
    "load_model",
    "resolve_model",
    "shipped_models",
    "train_classifier",
]
