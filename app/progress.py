"""Progress on a terminal as the ``progress(done, total)`` callback core takes.

A tqdm bar that goes away when the work ends; on a log or pipe, one line per stage as
it ends (``render: 2.4 s``), so a log holds no carriage returns.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from tqdm import tqdm


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


class StageBar(tqdm):
    """A tqdm bar on a terminal; elsewhere one line per stage (each description) as it ends
    (none for a stage ended by an exception: the error line says what happened)."""

    def __init__(self, *args, **kwargs) -> None:
        self._stream = kwargs.get("file") or sys.stderr
        self._log = not _is_terminal(self._stream)
        if self._log:
            kwargs["disable"] = True
        kwargs.setdefault("leave", False)
        super().__init__(*args, **kwargs)
        self._stage: str = kwargs.get("desc") or ""
        self._t0 = time.perf_counter()
        self._ended = False

    def _end_stage(self) -> None:
        if self._log and self._stage:
            print(f"{self._stage}: {time.perf_counter() - self._t0:.1f} s", file=self._stream,
                  flush=True)

    def set_description(self, desc: str | None = None, refresh: bool = True) -> None:
        if self._log and desc != self._stage:
            self._end_stage()
            self._stage, self._t0 = desc or "", time.perf_counter()
        super().set_description(desc, refresh)

    def __exit__(self, exc_type, exc_value, traceback):
        if exc_type is not None:
            self._ended = True
        return super().__exit__(exc_type, exc_value, traceback)

    def close(self) -> None:
        if not self._ended:
            self._ended = True
            self._end_stage()
        super().close()


@contextmanager
def progress_bar(desc: str, total: int | None = 1, **options
                 ) -> Iterator[Callable[[int, int], None]]:
    """A :class:`StageBar` labelled ``desc`` while the ``with`` block runs, as a
    ``progress(done, total)`` callback; ``options`` go to tqdm."""
    with StageBar(total=total, desc=desc, **options) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        yield progress
