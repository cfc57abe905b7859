"""OptionError: options named by their fields in the library, by their flags in the CLI."""

from __future__ import annotations

import pytest
from terratheme.app.cli import flag_of
from terratheme.core.errors import CorruptFileError, OptionError, TerrathemeError


def test_fields_spelled_by_name_or_by_the_callers_spelling():
    exc = OptionError("use {tile} or a smaller {size}; {reduce_palette} too")
    assert isinstance(exc, TerrathemeError)
    assert exc.fields == ("tile", "size", "reduce_palette")
    assert str(exc) == "use tile or a smaller size; reduce_palette too"
    assert exc.spelled(flag_of) == "use --tile or a smaller --size; --reduce-palette too"
    assert exc.spelled(str.upper) == "use TILE or a smaller SIZE; REDUCE_PALETTE too"


def test_a_place_in_front_keeps_the_fields_even_with_braces_in_it():
    exc = OptionError("{tile} 17 is not a resolution").at("maps/{odd}.ttproj")
    assert isinstance(exc, OptionError)
    assert str(exc) == "maps/{odd}.ttproj: tile 17 is not a resolution"
    assert exc.spelled(flag_of) == "maps/{odd}.ttproj: --tile 17 is not a resolution"


def test_other_errors_take_a_place_in_front_and_keep_their_type():
    exc = CorruptFileError("truncated").at("a.ttp")
    assert type(exc) is CorruptFileError and str(exc) == "a.ttp: truncated"


def test_a_message_without_fields_is_itself():
    assert OptionError("plain").fields == ()
    assert str(OptionError("plain")) == "plain"
    with pytest.raises(OptionError, match="^size 3x5 is not square$"):
        raise OptionError("{size} 3x5 is not square")
