"""Output paths, checked before a command starts its work.

Every command calls :func:`check_outputs` with every file it may write (sidecars
included) right after reading its arguments, so a bad output path costs no work. The
folders it makes for them are taken away again, when still empty, if the command then
fails (:func:`folders_made_for_outputs`, around each command in ``app.cli``).
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

from terratheme.core.errors import TerrathemeError
from terratheme.core.io.atomic import missing_folders, remove_empty_folders, special_file

#: the folders :func:`check_outputs` made for the running command, oldest first
_MADE: contextvars.ContextVar[list[Path] | None] = contextvars.ContextVar("made", default=None)


class MadeFolders:
    """The folders made for a command's outputs (:func:`folders_made_for_outputs`)."""

    def __init__(self) -> None:
        self.paths: list[Path] = []

    def remove_empty(self) -> None:
        """Remove them, newest first, where nothing has been put in them."""
        remove_empty_folders(reversed(self.paths))
        self.paths.clear()


@contextlib.contextmanager
def folders_made_for_outputs() -> Iterator[MadeFolders]:
    """Record the folders :func:`check_outputs` makes; on an exception remove the empty
    ones (a failed command leaves no new folder behind). The caller may also call
    :meth:`MadeFolders.remove_empty` itself for a command that failed without one."""
    made = MadeFolders()
    token = _MADE.set(made.paths)
    try:
        yield made
    except BaseException:
        made.remove_empty()
        raise
    finally:
        _MADE.reset(token)


def _resolved(path: Path) -> Path:
    try:
        return path.resolve()
    except (RuntimeError, OSError) as exc:
        loop = isinstance(exc, RuntimeError) or exc.errno == errno.ELOOP
        why = "a symlink loop" if loop else (exc.strerror or str(exc))
        raise TerrathemeError(f"{path}: cannot follow the path ({why})") from None


def _file_id(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _check_subfolders(out: Path, folder: Path) -> None:
    """Refuse a symlinked folder between ``folder`` (the output folder named) and ``out``."""
    try:
        parts = out.parent.relative_to(folder).parts
    except ValueError:
        return
    here = folder
    for part in parts:
        here = here / part
        if here.is_symlink():
            raise TerrathemeError(f"{here}: is a symbolic link; an output folder's subfolders "
                                  "must be real folders (remove the link)")


def check_file_names(paths: Iterable[str | os.PathLike | None]) -> None:
    """Refuse an output file name that ends in '/' (a folder's; ``Path`` drops the slash,
    so ``x.ttproj/`` would be written as the file ``x.ttproj``). None entries are skipped."""
    for raw in paths:
        if raw is not None and os.fspath(raw).endswith(("/", os.sep)):
            raise TerrathemeError(f"{os.fspath(raw)}: ends in '/', so it names a folder; "
                                  "name the output file")


def check_outputs(outputs: Iterable[str | os.PathLike | None], *,
                  inputs: Iterable[str | os.PathLike | None] = (),
                  folder: str | os.PathLike | None = None) -> list[Path]:
    """Check the files a command will write and make their folders; returns the non-None
    ``outputs``.

    TerrathemeError when an output is or names a folder, a pipe or device, an input (after links,
    or by inode), named twice, under a symlinked subfolder of ``folder`` (an export's), a
    symlink loop, or in a folder that cannot be made or written. None entries are skipped.
    """
    outputs = [p for p in outputs if p is not None]
    check_file_names(outputs)
    outs = [Path(p) for p in outputs]
    ins = [(Path(p), _resolved(Path(p)), _file_id(Path(p))) for p in inputs if p is not None]
    seen: dict[Path, Path] = {}
    for out in outs:
        real = _resolved(out)
        if out.is_dir():
            raise TerrathemeError(f"{out}: is a folder, not an output file")
        kind = special_file(out)
        if kind is not None:
            raise TerrathemeError(f"{out}: is {kind}, not an output file")
        ident = _file_id(out)
        for src, src_real, src_id in ins:
            if real == src_real or (ident is not None and ident == src_id):
                raise TerrathemeError(f"{out}: is also an input ({src}); write the output "
                                      "elsewhere")
        if real in seen:
            raise TerrathemeError(f"{out}: two outputs would be written to the same file")
        seen[real] = out
        if folder is not None:
            _check_subfolders(out, Path(folder))
        parent = out.parent if str(out.parent) else Path(".")
        missing = missing_folders([out])
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            # A folder on the way that is a link to nothing: name it, not "File exists".
            dangling = next((p for p in (parent, *parent.parents)
                             if p.is_symlink() and not p.exists()), None)
            if dangling is not None:
                raise TerrathemeError(f"{out}: the folder {dangling} is a symlink to "
                                      f"{os.readlink(dangling)}, which does not exist") from None
            raise TerrathemeError(f"{out}: cannot make the folder {parent} ({exc.strerror})"
                                  ) from None
        made = _MADE.get()
        if made is not None:
            made.extend(reversed(missing))  # oldest first
        if not os.access(parent, os.W_OK | os.X_OK):
            raise TerrathemeError(f"{out}: the folder {parent} is not writable")
    return outs


def check_image_outputs(paths: Iterable[str | os.PathLike | None], *, channels: int) -> None:
    """Refuse, before any work, an image output whose extension no image writer takes or
    whose writer refuses ``channels`` channels (None entries are skipped):
    :func:`core.io.image_format.check_writable_format`."""
    from terratheme.core.io.image_format import check_writable_format

    for path in paths:
        if path is not None:
            check_writable_format(path, channels=channels)


def check_mask_sizes(pairs: Iterable[tuple[str | os.PathLike, str | os.PathLike]],
                     what: str = "label mask") -> None:
    """Refuse a ``(photo, mask)`` pair whose sizes differ, from the files' headers (before
    any work); the message calls the mask ``what``."""
    from terratheme.core.io.images import image_info

    for photo, mask in pairs:
        p, m = image_info(photo), image_info(mask)
        if (p.width, p.height) != (m.width, m.height):
            raise TerrathemeError(f"{mask}: the {what} is {m.width} x {m.height} pixels but its "
                                  f"photo {photo} is {p.width} x {p.height}: a mask must have "
                                  "the photo's size")
