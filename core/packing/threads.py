"""A batched lookup kernel run on threads: pieces of the batch taken as threads come free.

The kernels of :mod:`core.packing.batch` and :mod:`core.packing.sweep`
release the GIL (``nogil``), so a pool of Python threads runs them in
parallel; :func:`on_threads` hands out the pieces and gathers the first
texel outside the layer.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from threading import Lock

import numpy as np


def on_threads(kernel: Callable[..., int], xs: np.ndarray, ys: np.ndarray, tables: tuple,
               out: np.ndarray, parts: int, piece: int | None = None) -> int:
    """``kernel(xs, ys, *tables, out)`` over pieces of a batch on ``parts`` threads.

    The kernels release the GIL (``nogil``); the calling thread works too, the
    others are a shared pool of Python threads. Each thread takes the next
    piece of ``piece`` texels (None: of ``parts`` equal slices, for the bucket
    strategy, whose larger slices sort into fuller buckets) until none is
    left, so a thread held back (by other work on the machine) or slow to wake
    leaves its share to the others. Python threads rather than a numba
    ``prange``: OpenMP's workers spin while they wait, which on a busy
    machine took CPU from the slice still working (10^6 texels on 2 threads,
    load 2.5, CPU time: Chesapeake 9.1 ns with ``prange``, 6.8 ns on the pool,
    one thread 6.7 ns).

    Returns
    -------
    bad : int
        Position of the first coordinate outside the layer, or -1.
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
