"""Argument types the subcommands share: integers joined by a separator (``WxH``, ``x,y,w,h``).

Each raises ``argparse.ArgumentTypeError`` with one line naming the expected form (exit 2).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable


def int_tuple(what: str, form: str, count: int, separator: str = "x", *,
              one_for_all: bool = False) -> Callable[[str], tuple[int, ...]]:
    """An argparse type: ``count`` integers joined by ``separator`` (case-insensitive).

    Bad text: ``"{what} must be {form}, got '{text}'"``. ``one_for_all``: one integer
    alone stands for all of them (``16`` is ``16x16``).
    """

    def parse(text: str) -> tuple[int, ...]:
        message = f"{what} must be {form}, got {text!r}"
        try:
            values = [int(v) for v in text.lower().split(separator)]
        except ValueError as exc:
            raise argparse.ArgumentTypeError(message) from exc
        if one_for_all and len(values) == 1:
            values *= count
        if len(values) != count:
            raise argparse.ArgumentTypeError(message)
        return tuple(values)

    return parse



def unit_fraction(what: str) -> Callable[[str], float]:
    """An argparse type: a number in (0, 1] (``what`` names it in the message)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"{what} must be a number, got {text!r}") from exc
        if not 0.0 < value <= 1.0:
            raise argparse.ArgumentTypeError(f"{what} must be in (0, 1], got {text!r}")
        return value

    return parse

#: how ``--legend FILE`` is described, after what it names
LEGEND_FORMS = ('(JSON {"1": "Building", ...}, a list of {"id", "name"} or CSV lines '
                '"1,Building"; docs/formats.md)')


def add_legend_option(parser: argparse.ArgumentParser, names: str) -> None:
    """``--legend FILE``: a mask's class names; ``names`` says what they name (help text)."""
    parser.add_argument("--legend", metavar="FILE", help=f"{names} {LEGEND_FORMS}")
