"""Exception types raised by the core library.

Every error a user can cause is a :class:`TerrathemeError` (a ``ValueError``) whose
message names the problem, so the CLI shows one line instead of a traceback.
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
    """A bad option value. ``template`` names each option as ``{field}`` (its options
    dataclass field, no other braces); ``str()`` spells it as the field, :meth:`spelled`
    as the caller's name for it (the CLI: its flag).
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
