"""Opening a project for a command: the file read and its render style checked, up front.

:func:`core.model.project.load_project` checks every field it needs to build
the project; the render style in ``metadata["render"]`` is parsed by
:mod:`core.render.project` (core.model cannot import it: core.render builds
on core.model), so a command that loads a project checks the style at once
here, and a bad style is one line naming the file before any work.
"""

from __future__ import annotations

import os

from core.errors import CorruptFileError, TerrathemeError
from core.model.project import ThematicTexture, load_project


def load_checked_project(path: str | os.PathLike) -> ThematicTexture:
    """:func:`load_project`, then the project's render style checked; errors name ``path``."""
    from core.render.project import project_style

    project = load_project(path)
    try:
        project_style(project)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{path}: {exc}") from None
    return project
