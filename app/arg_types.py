"""Argument types the subcommands share: integers joined by a separator (``WxH``, ``x,y,w,h``).

Each is an argparse ``type=``: it returns the parsed tuple, or raises
``argparse.ArgumentTypeError`` with one line naming the expected form, which
argparse prints after the option's name (exit 2).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable


def int_tuple(what: str, form: str, count: int, separator: str = "x", *,
              one_for_all: bool = False) -> Callable[[str], tuple[int, ...]]:
    """An argparse type: ``count`` integers joined by ``separator`` (case-insensitive).

    Parameters
    ----------
    what, form : str
        The message on bad text: ``"{what} must be {form}, got '{text}'"``.
    count : int
        How many integers.
    separator : str
    one_for_all : bool
        One integer alone stands for all ``count`` of them (``16`` is ``16x16``).

    Examples
    --------
    >>> int_tuple("size", "WxH", 2)("640X360")
    (640, 360)
    >>> int_tuple("cell", "N or NxM", 2, one_for_all=True)("16")
    (16, 16)
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
    """An argparse type: a number in (0, 1] (``what`` names it in the message).

    Examples
    --------
    >>> unit_fraction("scale")("0.25")
    0.25
    """

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
    """``--legend FILE``: the class names of a mask (:mod:`core.io.legend`); ``names`` says
    what they name, for the help text."""
    parser.add_argument("--legend", metavar="FILE", help=f"{names} {LEGEND_FORMS}")
