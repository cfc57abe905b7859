"""A batched lookup kernel run on threads: pieces of the batch taken as threads come free."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from threading import Lock

import numpy as np


def on_threads(kernel: Callable[..., int], xs: np.ndarray, ys: np.ndarray, tables: tuple,
               out: np.ndarray, parts: int, piece: int | None = None) -> int:
    """``kernel(xs, ys, *tables, out)`` over pieces of a batch on ``parts`` threads.

    The kernels release the GIL; the calling thread works too, the others are a shared
    pool. Each thread takes the next piece of ``piece`` texels (None: ``parts`` equal
    slices, for the bucket strategy, whose larger slices fill fuller buckets), so a thread
    held back leaves its share to the others. Python threads, not numba's ``prange``,
    whose OpenMP workers spin while waiting. Returns the first bad texel or -1.
    """
    n = xs.size
    if n == 0:
        return -1
    parts = max(1, parts)
    size = -(-n // parts) if piece is None else max(1, piece)
    starts = range(0, n, size)
    threads = min(parts, len(starts))
    todo = iter(starts)
    lock = Lock()

    def work() -> int:
        # The first bad texel among the pieces this thread took, or n.
        first = n
        while True:
            with lock:
                a = next(todo, -1)
            if a < 0:
                return first
            k = int(kernel(xs[a: a + size], ys[a: a + size], *tables, out[a: a + size]))
            if k >= 0:
                first = min(first, a + k)

    later = [_pool(threads - 1).submit(work) for _ in range(threads - 1)]
    first = min([work()] + [f.result() for f in later])
    return first if first < n else -1


#: The lookup threads: (their number, the pool), made on first use, remade larger on demand.
_POOL: list[tuple[int, ThreadPoolExecutor]] = []


def _pool(threads: int) -> ThreadPoolExecutor:
    threads = max(1, threads)
    if not _POOL or _POOL[0][0] < threads:
        _POOL[:] = [(threads, ThreadPoolExecutor(threads, thread_name_prefix="tt-lookup"))]
    return _POOL[0][1]
