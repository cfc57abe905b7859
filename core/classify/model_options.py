"""The classifier options a model file may hold, as JSON, with the type and range of each.

Unknown options are refused; those of removed methods (``_RETIRED``) are accepted at
their "off" value.
"""

from __future__ import annotations

import math
from dataclasses import asdict

from terratheme.core.classify.extra_trees import MAX_DEPTH, MAX_TREES
from terratheme.core.classify.features import FeatureOptions, FeatureSet
from terratheme.core.classify.regularise import Regularisation, RegulariseOptions
from terratheme.core.classify.supervised_options import SupervisedOptions


def options_to_json(options: SupervisedOptions) -> dict:
    """The options as plain JSON: enums by value, features and regularisation nested."""
    d = asdict(options)
    d["features"]["feature_set"] = options.features.feature_set.value
    d["regularisation"]["method"] = options.regularisation.method.value
    return d


def number_rule(lo: float, hi: float, *, whole: bool = False, optional: bool = False):
    """A rule ``(value, name) -> value``: a finite number (a whole one if ``whole``) in
    ``lo..hi`` (None if ``optional``), else ``ValueError``."""
    def check(value, name):
        if value is None and optional:
            return None
        kinds = int if whole else int | float
        if (not isinstance(value, kinds) or isinstance(value, bool)
                or not math.isfinite(value) or not lo <= value <= hi):
            raise ValueError(f"{name} must be a {'whole ' if whole else ''}number in "
                             f"{lo:g}..{hi:g}, not {repr(value)[:30]}")
        return value
    return check


def _numbers(lo: float, hi: float, *, whole: bool = False, most: int = 16):
    """A rule: a list of at most ``most`` numbers, each as :func:`number_rule`."""
    one = number_rule(lo, hi, whole=whole)

    def check(value, name):
        if not isinstance(value, list) or len(value) > most:
            raise ValueError(f"{name} must be a list of at most {most} numbers")
        return tuple(one(v, name) for v in value)
    return check


def _flag(value, name):
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be true or false, not {repr(value)[:30]}")
    return value


def _optional_flag(value, name):
    return None if value is None else _flag(value, name)


def _choice(enum_type):
    def check(value, name):
        try:
            return enum_type(value)
        except (ValueError, TypeError):
            raise ValueError(f"{name} must be one of "
                             f"{', '.join(e.value for e in enum_type)}") from None
    return check


#: every option a model file may hold, with its type and range (missing ones take
#: their defaults; bounds keep a hostile file from costing unbounded work at predict time)
_FEATURE_RULES = {
    "feature_set": _choice(FeatureSet), "scale": number_rule(1, 64, whole=True),
    "sigmas": _numbers(1e-3, 64), "hessian": _flag, "position": _flag,
    "ridge_sigmas": _numbers(1e-3, 64), "structure": _flag,
}
_REGULARISE_RULES = {
    "method": _choice(Regularisation), "sigma": number_rule(1e-3, 64),
    "edge_sigma_spatial": number_rule(1e-3, 256), "edge_sigma_colour": number_rule(1e-3, 1e4),
}
_OPTION_RULES = {
    "ignore_classes": _numbers(0, 255, whole=True, most=256),
    "n_trees": number_rule(1, MAX_TREES, whole=True),
    "max_depth": number_rule(1, MAX_DEPTH, whole=True),
    "min_samples": number_rule(1, 1 << 30, whole=True),
    "max_samples_per_class": number_rule(1, 1 << 30, whole=True), "balance": _flag,
    "seed": number_rule(0, 2**32 - 1, whole=True), "tile": number_rule(16, 1 << 16, whole=True),
    "prior_power": number_rule(0, 1, optional=True),
    "grow_colour": number_rule(0, 1e4, optional=True),
    "samples_per_pair": number_rule(1, 1 << 30, whole=True),
    "adapt": _optional_flag,
}
#: options of removed methods in earlier files: the values they may hold (None: any,
#: a parameter of a removed choice); any other value is refused
_RETIRED = {
    "options": {"forest": ("extra-trees",), "active_vars": None, "target_prior_power": (0,)},
    "options.features": {"normalise": ("none",), "skimage_sigma_max": None,
                         "profile_radii": ([],), "relative": (False,)},
    "options.regularisation": {"region_size": None, "ruler": None},
}


def _apply_rules(d: object, rules: dict, where: str) -> dict:
    if not isinstance(d, dict):
        raise ValueError(f"{where} must be an object")
    retired = _RETIRED[where]
    unknown = sorted(set(d) - set(rules) - set(retired) - {"features", "regularisation"})
    if unknown:
        raise ValueError(f"unknown option {where}.{unknown[0][:40]}")
    for k in set(d) & set(retired):
        if retired[k] is not None and d[k] not in retired[k]:
            raise ValueError(f"{where}.{k} {repr(d[k])[:30]} is no longer supported")
    return {k: rule(d[k], f"{where}.{k}") for k, rule in rules.items() if k in d}


def options_from_json(d: object) -> SupervisedOptions:
    """Options from :func:`options_to_json`'s JSON, every field checked (``ValueError``)."""
    rest = _apply_rules(d, _OPTION_RULES, "options")
    features = FeatureOptions(**_apply_rules(d.get("features"), _FEATURE_RULES,
                                             "options.features"))
    regularisation = RegulariseOptions(**_apply_rules(d.get("regularisation"),
                                                      _REGULARISE_RULES,
                                                      "options.regularisation"))
    return SupervisedOptions(features=features, regularisation=regularisation, **rest)
