"""Exception types raised by the core library.

Every error a user can cause (bad file, wrong size, unknown theme, truncated
stream, empty image) is raised as a :class:`TerrathemeError` (a ``ValueError``)
with a message that names the problem, so the CLI and the app can show one
clear line instead of a traceback.
"""


class TerrathemeError(ValueError):
    """A problem with the user's input: the message says what and where."""


class CorruptFileError(TerrathemeError):
    """A file exists but its content is damaged, truncated or not ours."""


class UnsupportedVersionError(TerrathemeError):
    """A file was written by a newer format version than this build reads."""
