"""A progress bar on the terminal as the ``progress(done, total)`` callback core takes.

Every long core call takes ``progress(done, total)``; the commands show it as
a tqdm bar that goes away when the work ends (``leave=False``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from tqdm import tqdm


@contextmanager
def progress_bar(desc: str, total: int | None = 1, **options
                 ) -> Iterator[Callable[[int, int], None]]:
    """A tqdm bar shown while the ``with`` block runs, as a ``progress(done, total)`` callback.

    Parameters
    ----------
    desc : str
        The bar's label.
    total : int or None
        The first total shown (each call sets it again).
    **options
        Further tqdm options (``unit``, ``disable``).
    """
    with tqdm(total=total, desc=desc, leave=False, **options) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        yield progress
