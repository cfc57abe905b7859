"""Output paths, checked before a command starts its work.

Every command calls :func:`check_outputs` right after reading its arguments,
so a bad output path costs no work: a path that is a folder, an output that
is also an input, two outputs on one path, or a folder that cannot be made
or written. Missing output folders are made (every command alike).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from terratheme.core.errors import TerrathemeError


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and a.samefile(b)
    except OSError:
        return False


def check_outputs(outputs: Iterable[str | os.PathLike | None], *,
                  inputs: Iterable[str | os.PathLike | None] = ()) -> list[Path]:
    """Check (and prepare the folders of) the files a command will write.

    Parameters
    ----------
    outputs : paths (None entries are skipped)
    inputs : paths the command reads (None entries are skipped)

    Returns
    -------
    outputs : list of Path, the non-None outputs

    Raises
    ------
    TerrathemeError
        An output is a folder, is one of the inputs, appears twice, or its
        folder cannot be made or is not writable.
    """
    outs = [Path(p) for p in outputs if p is not None]
    ins = [Path(p) for p in inputs if p is not None]
    seen: list[Path] = []
    for out in outs:
        if out.is_dir():
            raise TerrathemeError(f"{out}: is a folder, not an output file")
        for src in ins:
            if out.resolve() == src.resolve() or _same_file(out, src):
                raise TerrathemeError(f"{out}: is also an input; write the output elsewhere")
        for other in seen:
            if out.resolve() == other.resolve():
                raise TerrathemeError(f"{out}: two outputs would be written to the same file")
        seen.append(out)
        folder = out.parent if str(out.parent) else Path(".")
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise TerrathemeError(f"{out}: cannot make the folder {folder} ({exc.strerror})"
                                  ) from None
        if not os.access(folder, os.W_OK | os.X_OK):
            raise TerrathemeError(f"{out}: the folder {folder} is not writable")
    return outs


def check_image_outputs(paths: Iterable[str | os.PathLike | None]) -> None:
    """Refuse, before any work, an image output whose extension no image writer takes
    (None entries are skipped): :func:`core.io.image_format.check_writable_format`."""
    from terratheme.core.io.image_format import check_writable_format

    for path in paths:
        if path is not None:
            check_writable_format(path)


def check_mask_sizes(pairs: Iterable[tuple[str | os.PathLike, str | os.PathLike]],
                     what: str = "label mask") -> None:
    """Refuse a ``(photo, mask)`` pair whose sizes differ, from the two files' headers
    (before any pixel is read or any work starts); the message names both files and
    calls the mask ``what``."""
    from terratheme.core.io.images import image_info

    for photo, mask in pairs:
        p, m = image_info(photo), image_info(mask)
        if (p.width, p.height) != (m.width, m.height):
            raise TerrathemeError(f"{mask}: the {what} is {m.width} x {m.height} pixels but its "
                                  f"photo {photo} is {p.width} x {p.height}: a mask must have "
                                  "the photo's size")
