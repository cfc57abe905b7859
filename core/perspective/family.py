"""The seed's family of prefiltered copies (Kovalev & Tarasov, "filtering of the source
texture" and its table), built level by level.

For a wrapping ``2^q x 2^p`` texture and each orientation (toward U; toward V as the
transposed texture, so one lookup serves both), copy ``(a, b, tan)`` tiles the plane
with cells ``2^a`` texels along the tilted side and ``2^b`` across, sloping ``tan``:
cell ``(m, k)`` is the texture's mean over the parallelogram centred at ``((k + 1/2)
2^a, (m + 1/2) 2^b)`` (``b = 0``: the line through that row, read bilinearly). At
``lambda = 2^(a-b) = 2^i`` there are ``2^(i-1) + 1`` skews (:func:`skew_values`);
``lambda = 1`` copies are the mip levels; about ``(k + 1) * 4/3 * W' H'`` cells for
``k = log2`` of the largest ``lambda``. Where a side is exhausted one skew is kept,
so memory stays proportional to the texels for any aspect ratio.

Build (:func:`build_family`), each step from the previous, threaded over rows:

1. ``b = 0``: per skew, the texture sheared along it and summed in pairs along the
   line, level after level: copies ``(i, 0, tan)``;
2. ``b > 0``: copy ``(a, b, tan)`` is the mean of 4 cells of ``(a-1, b-1, tan)``;
3. where the cross side is exhausted, longer copies are pairs along;
4. the mip levels are 2 x 2 means.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from terratheme.core.errors import TerrathemeError
from terratheme.core.perspective.texture import level_shape, to_storage

Progress = Callable[[int, int], None]


def skew_values(i: int, oversampling: int = 1) -> np.ndarray:
    """The skews kept at ``lambda = 2^i``, (count,) float64: ``tan = 2 j / c``, ``|j| <= c //
    2``, ``c = oversampling * 2^(i-1)``: the seed's spacing on a grid through 0 (the seed's
    is offset half a step and misses the commonest, axis-aligned footprint).
    """
    if i <= 0:
        return np.zeros(1)
    c = oversampling * (1 << (i - 1))
    q = c // 2
    return 2.0 * np.arange(-q, q + 1) / c


@dataclass(frozen=True)
class ParallelogramFamily:
    """All prefiltered copies, packed for the lookup kernel.

    ``buf`` (T, C): every cell, copy after copy (row-major), in the storage type.
    ``start`` (2, L+1, L+1) int64: ``start[o, a, b]`` is where the first skew of copy
    ``(a, b)`` tilted toward U (``o = 0``) or V (``o = 1``, transposed frame) begins,
    -1 if absent; skew ``s`` begins ``s * rows * cols`` later; ``start[1, l, l]`` is
    the mip level ``start[0, l, l]``. ``count``: skews kept for ``(o, a, b)``.
    """

    buf: np.ndarray
    start: np.ndarray
    count: np.ndarray
    grid_size: tuple[int, int]
    max_lambda_log2: int
    skew_oversampling: int

    @property
    def nbytes(self) -> int:
        """Memory of the prefiltered cells (the tables are negligible)."""
        return int(self.buf.nbytes)

    def shape(self, toward: int, a: int, b: int) -> tuple[int, int]:
        """``(rows, cols)`` of copy ``(a, b)`` in its own frame."""
        along, across = _sides(self.grid_size, toward)
        return level_shape(across, along, b)[0], level_shape(across, along, a)[1]

    def copy(self, toward: int, a: int, b: int, s: int = 0) -> np.ndarray:
        """Skew ``s`` of copy ``(a, b)`` as a ``(rows, cols, C)`` view in its own frame
        (mip levels, ``a = b``, in the texture's frame for both orientations)."""
        top = self.start.shape[1]
        if not (0 <= a < top and 0 <= b < top and self.start[toward, a, b] >= 0
                and 0 <= s < self.count[toward, a, b]):
            raise KeyError(f"no copy toward={toward} a={a} b={b} s={s}")
        off = int(self.start[toward, a, b])
        rows, cols = self.shape(0 if a == b else toward, a, b)
        off += s * rows * cols
        return self.buf[off : off + rows * cols].reshape(rows, cols, -1)


def _sides(grid_size: tuple[int, int], toward: int) -> tuple[int, int]:
    """``(along, across)`` texels of the grid for an orientation."""
    w, h = grid_size
    return (w, h) if toward == 0 else (h, w)


def _log2(n: int) -> int:
    return int(n).bit_length() - 1


def family_layout(grid_size: tuple[int, int], max_lambda_log2: int,
                  skew_oversampling: int = 1) -> tuple[np.ndarray, np.ndarray, int]:
    """Where every copy goes: ``(start, count, total_cells)`` (see :class:`ParallelogramFamily`)."""
    w, h = grid_size
    top = max(_log2(w), _log2(h))
    k = max(0, int(max_lambda_log2))
    start = np.full((2, top + 1, top + 1), -1, np.int64)
    count = np.zeros((2, top + 1, top + 1), np.int64)
    offset = 0
    # mip levels, shared by both orientations
    for lvl in range(top + 1):
        r, c = level_shape(h, w, lvl)
        start[:, lvl, lvl] = offset
        count[:, lvl, lvl] = 1
        offset += r * c
    for o in (0, 1):
        along, across = _sides(grid_size, o)
        pa, px = _log2(along), _log2(across)
        for b in range(px + 1):
            # an exhausted cross side keeps copies of any length, one skew
            a_max = pa if b == px else min(pa, b + k)
            for a in range(b + 1, a_max + 1):
                n_skews = 1 if b == px else len(skew_values(a - b, skew_oversampling))
                rows = level_shape(across, along, b)[0]
                cols = level_shape(across, along, a)[1]
                start[o, a, b] = offset
                count[o, a, b] = n_skews
                offset += n_skews * rows * cols
    return start, count, offset


@njit(cache=True, inline="always")
def _put(buf, idx, c, x, top):
    """``buf[idx, c] = x``, rounded and clipped to ``[0, top]`` for integer storage (top > 0)."""
    if top > 0.0:
        x = min(max(math.floor(x + 0.5), 0.0), top)
    buf[idx, c] = x


@njit(cache=True, parallel=True)
def sheared_cells(grid, taus, dest, top, buf):
    """Step 1: the ``b = 0`` copies of every skew, written into ``buf`` (T, C).

    ``grid`` (R, N, C) is the texture in the orientation's frame (rows across,
    columns along); ``taus`` (S,) the skews (rows across per column along);
    ``dest[s, i]`` where copy ``(i, 0)`` of skew ``s`` starts in ``buf`` (-1: not
    kept); ``top`` the storage type's largest value (0 for float).
    """
    rows, n, nc = grid.shape
    levels = dest.shape[1] - 1
    mask = rows - 1
    # per skew and column: whole rows and fraction of the line's offset (rows r + d + f)
    shift = np.empty((taus.shape[0], n), np.int64)
    frac = np.empty((taus.shape[0], n), np.float32)
    for s in range(taus.shape[0]):
        for j in range(n):
            y = taus[s] * (j + 0.5)
            fl = math.floor(y)
            shift[s, j] = int(fl)
            frac[s, j] = y - fl
    for job in prange(taus.shape[0] * rows):
        s = job // rows
        r = job % rows
        # row r of the sheared image: the line through (0, r + 1/2) with slope tau
        line = np.empty((n, nc), np.float32)
        for j in range(n):
            j0 = (r + shift[s, j]) & mask
            j1 = (j0 + 1) & mask
            f = frac[s, j]
            for c in range(nc):
                line[j, c] = grid[j0, j, c] + f * (np.float32(grid[j1, j, c]) - grid[j0, j, c])
        # sums in pairs along the line, level after level (in place)
        length = n
        for i in range(1, levels + 1):
            length //= 2
            for kk in range(length):
                for c in range(nc):
                    line[kk, c] = line[2 * kk, c] + line[2 * kk + 1, c]
            off = dest[s, i]
            if off < 0:
                continue
            inv = 1.0 / (1 << i)
            for kk in range(length):
                # the cell whose centre line is this row: m = r + tau * u_k
                m = (r + int(math.floor(taus[s] * (kk + 0.5) * (1 << i) + 0.5))) & mask
                idx = off + m * length + kk
                for c in range(nc):
                    _put(buf, idx, c, line[kk, c] * inv, top)


#: columns of a step-2 job: parent start, rows, cols; child start, rows, cols; row shift
JOB_FIELDS = 7


@njit(cache=True, parallel=True)
def halved_cells(jobs, row_starts, top, buf):
    """Steps 2-4: every child copy of ``jobs`` (J, JOB_FIELDS) from its parent in ``buf``.

    Child cell ``(m, k)`` is the mean of the parent's rows ``2m, 2m+1`` (mod its
    rows) shifted by ``-delta`` in column ``2k`` and by ``+delta`` in column ``2k+1``
    (mod its columns): the diagonal step for ``delta = tan 2^(i-1)``, a mip level for
    ``delta = 0``, pairs along where the parent has one row. ``row_starts``
    (J + 1,): cumulative child rows, the parallel loop's range.
    """
    nc = buf.shape[1]
    for t in prange(row_starts[-1]):
        job = np.searchsorted(row_starts, t, side="right") - 1
        p_off, pr, pc, c_off, _, cols, delta = jobs[job]
        m = t - row_starts[job]
        r0 = (2 * m - delta) % pr
        r1 = (r0 + 1) % pr
        r2 = (2 * m + delta) % pr
        r3 = (r2 + 1) % pr
        for kk in range(cols):
            k0 = (2 * kk) % pc
            k1 = (2 * kk + 1) % pc
            for c in range(nc):
                x = 0.25 * (float(buf[p_off + r0 * pc + k0, c])
                            + float(buf[p_off + r1 * pc + k0, c])
                            + float(buf[p_off + r2 * pc + k1, c])
                            + float(buf[p_off + r3 * pc + k1, c]))
                _put(buf, c_off + m * cols + kk, c, x, top)


def build_family(grid: np.ndarray, max_lambda_log2: int, skew_oversampling: int = 1,
                 dtype: np.dtype | type = np.float32,
                 progress: Progress | None = None) -> ParallelogramFamily:
    """Prefilter the family of copies, level by level (the module's steps).

    ``grid`` (H', W', C) in stored units, sides powers of two; ``max_lambda_log2``:
    ``k``, the largest ``log2(lambda)`` kept where the cross side is not exhausted;
    ``skew_oversampling`` 1 or 2 times the seed's skews; ``dtype`` float32, uint8 or
    uint16 (filtered in floating point, rounded once per level).
    """
    h, w, nc = grid.shape
    if h & (h - 1) or w & (w - 1):
        raise TerrathemeError(f"the family needs power-of-two sides, got {h} x {w}")
    if skew_oversampling not in (1, 2):
        raise TerrathemeError(f"skew_oversampling must be 1 or 2, got {skew_oversampling}")
    k = max(0, int(max_lambda_log2))
    so = skew_oversampling
    start, count, total = family_layout((w, h), k, so)
    dt = np.dtype(dtype)
    top = float(np.iinfo(dt).max) if dt.kind == "u" else 0.0
    buf = np.empty((total, nc), dt)
    done = 0

    def report(cells: int) -> None:
        nonlocal done
        done += cells
        if progress is not None:
            progress(done, total)

    # the mip level 0: the grid itself
    level0 = grid.reshape(-1, nc)
    buf[: h * w] = level0 if grid.dtype == dt else to_storage(level0, dt)
    report(h * w)
    # step 1, per orientation: every b = 0 copy in one pass
    for o in (0, 1):
        g = grid if o == 0 else np.ascontiguousarray(grid.transpose(1, 0, 2))
        taus, dest = _sheared_jobs(start, count, o, g.shape[0], g.shape[1], so)
        if len(taus):
            sheared_cells(g, taus, dest, top, buf)
            report(int(sum(g.shape[0] * (g.shape[1] >> i) for s in range(len(taus))
                           for i in range(dest.shape[1]) if dest[s, i] >= 0)))
    # steps 2-4, one pass per length along (every parent is one level shorter)
    for a in range(1, start.shape[1]):
        jobs = _halving_jobs(start, count, (w, h), k, so, a)
        if len(jobs):
            rows = jobs[:, 4]
            row_starts = np.concatenate([[0], np.cumsum(rows)]).astype(np.int64)
            halved_cells(jobs, row_starts, top, buf)
            report(int((jobs[:, 4] * jobs[:, 5]).sum()))
    return ParallelogramFamily(buf, start, count, (w, h), k, so)


def _sheared_jobs(start, count, o, across, along, so):
    """Skews met at ``b = 0`` for orientation ``o`` and where each level keeps them."""
    pa = _log2(along)
    taus: list[float] = []
    rows: list[np.ndarray] = []
    for i in range(1, pa + 1):
        if start[o, i, 0] < 0:
            continue
        values = skew_values(i, so) if count[o, i, 0] > 1 else np.zeros(1)
        for s, tau in enumerate(values):
            if float(tau) not in taus:
                taus.append(float(tau))
                rows.append(np.full(pa + 1, -1, np.int64))
            rows[taus.index(float(tau))][i] = start[o, i, 0] + s * across * (along >> i)
    if not taus:
        return np.zeros(0), np.zeros((0, 1), np.int64)
    dest = np.stack(rows)
    # the pairwise sums stop at the longest level kept
    last = max(i for i in range(pa + 1) if (dest[:, i] >= 0).any())
    return np.array(taus), np.ascontiguousarray(dest[:, : last + 1])


def _halving_jobs(start, count, grid_size, k, so, a):
    """Step 2-4 jobs for every copy ``a`` long along (mip level ``a`` included)."""
    w, h = grid_size
    jobs = []
    # the mip level a from level a - 1
    pr, pc = level_shape(h, w, a - 1)
    cr, cc = level_shape(h, w, a)
    jobs.append((start[0, a - 1, a - 1], pr, pc, start[0, a, a], cr, cc, 0))
    for o in (0, 1):
        along, across = _sides(grid_size, o)
        px = _log2(across)
        for b in range(1, start.shape[2]):
            if a >= start.shape[1] or start[o, a, b] < 0 or a == b:
                continue
            i = a - b
            # the parent: one level shorter and narrower, or shorter only where the
            # cross side is exhausted
            pb = b - 1 if start[o, a - 1, b - 1] >= 0 and (a - 1 > b - 1) else b
            if pb == b and b != px:
                continue
            rows = level_shape(across, along, b)[0]
            cols = level_shape(across, along, a)[1]
            p_rows = level_shape(across, along, pb)[0]
            p_cols = level_shape(across, along, a - 1)[1]
            for s in range(int(count[o, a, b])):
                tau = skew_values(i, so)[s] if count[o, a, b] > 1 else 0.0
                # the parent's skew with the same tan (index in its own list)
                ps = _skew_index(tau, a - 1 - pb, so, int(count[o, a - 1, pb]))
                delta = int(round(tau * (1 << (i - 1)))) if pb == b - 1 else 0
                jobs.append((start[o, a - 1, pb] + ps * p_rows * p_cols, p_rows, p_cols,
                             start[o, a, b] + s * rows * cols, rows, cols, delta))
    return np.array(jobs, np.int64).reshape(-1, JOB_FIELDS)


def _skew_index(tau: float, i: int, so: int, n_skews: int) -> int:
    """Index of ``tau`` among the skews of a copy with ``lambda = 2^i`` and ``n_skews`` kept."""
    if n_skews == 1:
        return 0
    c = so * (1 << (i - 1))
    return int(round(tau * c / 2)) + c // 2
