"""Exception types raised by the core library.

Every error a user can cause (bad file, wrong size, unknown theme, truncated
stream, empty image) is raised as a :class:`TerrathemeError` (a ``ValueError``)
with a message that names the problem, so the CLI and the app can show one
clear line instead of a traceback. An option's bad value is an
:class:`OptionError`: it names the option by its field, which the CLI spells
as its flag.
"""

import string
from collections.abc import Callable


class TerrathemeError(ValueError):
    """A problem with the user's input: the message says what and where."""

    def at(self, where: str) -> "TerrathemeError":
        """The same error with ``where`` (a file's name) in front of its message."""
        return type(self)(f"{where}: {self}")


class CorruptFileError(TerrathemeError):
    """A file exists but its content is damaged, truncated or not ours."""


class UnsupportedVersionError(TerrathemeError):
    """A file was written by a newer format version than this build reads."""


class OptionError(TerrathemeError):
    """A bad option value; the message names options by their fields.

    Parameters
    ----------
    template : str
        The message, with each option it names as ``{field}`` (the options
        struct's field: ``{tile}``, ``{reduce_palette}``) and no other braces.

    ``str()`` spells each option as its field's name (the library's keyword);
    :meth:`spelled` as the caller's names for them (the CLI: its flags).
    """

    def __init__(self, template: str) -> None:
        self.template = template
        self.fields = tuple(f for _, f, _, _ in string.Formatter().parse(template) if f)
        super().__init__(self.spelled(str))

    def at(self, where: str) -> "OptionError":
        """The same error with ``where`` in front, its options still fields."""
        return OptionError(str(where).replace("{", "{{").replace("}", "}}") + ": " + self.template)

    def spelled(self, spell: Callable[[str], str]) -> str:
        """The message with each ``{field}`` replaced by ``spell(field)``."""
        return self.template.format_map({f: spell(f) for f in self.fields})
