"""Orthophoto classification into themes (design.md §3).

Unsupervised k-means themes (:func:`classify_unsupervised`, or :func:`fit_unsupervised`
to apply them per tile), Extra-Trees from scribbles or masks (:func:`train_classifier`),
or a saved or shipped model (:func:`load_model`); each gives a :class:`Classification`.
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
