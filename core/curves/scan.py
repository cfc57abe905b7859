"""Scans along a curve: numba kernels over a :class:`core.curves.plan.BlockPlan`.

Each kernel walks the blocks of the plan in curve order and, inside a block,
one of the precomputed local patterns, skipping texels outside the image (seed
section 2.2, ``Convert``); blocks wholly inside the image skip the bounds test.

Steps are 0-based and returned as ``uint32`` (a 65536^2 square has 2^32 steps);
ranks (how many image texels precede a texel along the curve) are ``int64``.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from terratheme.core.curves.plan import BlockPlan, CurveSquares, block_plan, plan_args
from terratheme.core.curves.square import Curve
from terratheme.core.errors import TerrathemeError


@numba.njit(cache=True, nogil=True)
def _runs_kernel(keys, ox, oy, width, height, b, bx, by, state, first_step, patterns, j0, j1,
                 steps, values, count, cur, last):  # pragma: no cover - numba
    # Blocks j0 .. j1-1 of a width x height image whose texels are in ``keys``, a window
    # with its top-left texel at column ox, row oy that holds those blocks' texels.
    # Resumable: stops before a block that might overflow ``steps``; returns where it stopped.
    side = 1 << b
    mask = side - 1
    cap = steps.size
    for j in range(j0, j1):
        if cap - count <= side * side:
            return count, j, cur, last
        x0 = np.int64(bx[j]) * side
        y0 = np.int64(by[j]) * side
        st = state[j]
        base = np.uint64(first_step[j])
        full = x0 + side <= width and y0 + side <= height
        for i in range(side * side):
            p = np.int64(patterns[st, i])
            x = x0 + (p & mask)
            y = y0 + (p >> b)
            if not full and (x >= width or y >= height):
                continue
            v = keys[height - 1 - y - oy, x - ox]
            # A value change closes the current run at the previous texel's step.
            if v != cur:
                steps[count] = last
                values[count] = cur
                count += 1
                cur = v
            last = base + np.uint64(i)
    return count, j1, cur, last


@numba.njit(cache=True, nogil=True)
def _inside_count(h, w, x0, y0, side):  # pragma: no cover - numba
    return (min(w, x0 + side) - x0) * (min(h, y0 + side) - y0)


@numba.njit(cache=True, nogil=True)
def _ranks_to_steps_kernel(ends, h, w, b, bx, by, state, first_step, patterns):  # pragma: no cover
    # ends[i]: number of image texels up to and including run i's last texel (1-based rank).
    side = 1 << b
    mask = side - 1
    out = np.empty(ends.size, np.uint32)
    r = 0
    done = np.int64(0)
    for j in range(bx.size):
        if r >= ends.size:
            break
        x0 = np.int64(bx[j]) * side
        y0 = np.int64(by[j]) * side
        count = _inside_count(h, w, x0, y0, side)
        base = np.uint64(first_step[j])
        if count == side * side:
            # Full block: the rank offset is the local step itself.
            while r < ends.size and ends[r] <= done + count:
                out[r] = base + np.uint64(ends[r] - done - 1)
                r += 1
        elif r < ends.size and ends[r] <= done + count:
            # Partial block: walk its pattern once, counting image texels.
            pat = patterns[state[j]]
            seen = done
            for i in range(side * side):
                p = np.int64(pat[i])
                if x0 + (p & mask) >= w or y0 + (p >> b) >= h:
                    continue
                seen += 1
                while r < ends.size and ends[r] == seen:
                    out[r] = base + np.uint64(i)
                    r += 1
        done += count
    return out, r


@numba.njit(cache=True, nogil=True)
def _steps_to_ranks_kernel(steps, h, w, b, bx, by, state, first_step, patterns):  # pragma: no cover
    side = 1 << b
    mask = side - 1
    out = np.full(steps.size, -1, np.int64)
    r = 0
    done = np.int64(0)
    for j in range(bx.size):
        x0 = np.int64(bx[j]) * side
        y0 = np.int64(by[j]) * side
        count = _inside_count(h, w, x0, y0, side)
        base = np.uint64(first_step[j])
        end = base + np.uint64(side * side)
        # Steps in blocks that miss the image have no rank (-1).
        while r < steps.size and np.uint64(steps[r]) < base:
            r += 1
        if count == side * side:
            while r < steps.size and np.uint64(steps[r]) < end:
                out[r] = done + np.int64(np.uint64(steps[r]) - base) + 1
                r += 1
        elif r < steps.size and np.uint64(steps[r]) < end:
            pat = patterns[state[j]]
            seen = done
            for i in range(side * side):
                p = np.int64(pat[i])
                if x0 + (p & mask) < w and y0 + (p >> b) < h:
                    seen += 1
                while r < steps.size and np.uint64(steps[r]) == base + np.uint64(i):
                    out[r] = seen
                    r += 1
        done += count
    return out


def scan_runs(
    keys: np.ndarray, curve: str | Curve, *, threads: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """Runs of equal values along the curve (seed section 2.2, ``Convert``).

    ``keys`` (H, W) integer, row 0 = top; ``threads`` stretches of blocks scanned at
    once, then stitched. Returns ``steps`` (R,) uint32, the strictly increasing
    0-based step of each run's last texel, and ``values`` (R,) of ``keys.dtype``.
    """
    keys = np.ascontiguousarray(keys)
    plan = block_plan(keys.shape[1], keys.shape[0], curve)
    nb = plan.bx.size
    cuts = np.linspace(0, nb, max(1, min(int(threads), nb)) + 1).astype(int)
    parts = [(int(a), int(z)) for a, z in zip(cuts[:-1], cuts[1:], strict=True) if z > a]

    def one(part: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        cap = max(2 * (1 << 2 * plan.b), keys.size // (64 * len(parts)))
        return _scan_stretch(keys, (0, 0), keys.shape[::-1], plan, part, cap)

    if len(parts) == 1:
        results = [one(parts[0])]
    else:
        with ThreadPoolExecutor(len(parts)) as pool:
            results = list(pool.map(one, parts))
    # Stitch: a run cut by a stretch boundary appears twice with one value; keep the later.
    return join_runs(results)


def _first_texel(plan: BlockPlan, j: int, shape: tuple[int, int]) -> tuple[int, int]:
    """(row, col) of block ``j``'s first image texel along the curve."""
    h, w = shape
    pat = plan.patterns[plan.state[j]].astype(np.int64)
    x = int(plan.bx[j]) * (1 << plan.b) + (pat & ((1 << plan.b) - 1))
    y = int(plan.by[j]) * (1 << plan.b) + (pat >> plan.b)
    i = int(np.argmax((x < w) & (y < h)))
    return h - 1 - int(y[i]), int(x[i])


def scan_square(
    keys: np.ndarray, width: int, height: int, curve: str | Curve, squares: CurveSquares,
    k: int,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`scan_runs` of square ``k`` alone, from its ``(h, w)`` window ``keys``.

    :func:`join_runs` stitches the squares' runs in curve order.
    """
    plan = block_plan(width, height, curve)
    x, y, w, h = squares.rect(k, width, height)
    keys = np.ascontiguousarray(keys)
    if keys.shape != (h, w):
        raise TerrathemeError(f"square {k} is {w} x {h} texels, got a {keys.shape} window")
    cap = max(2 * (1 << 2 * plan.b), keys.size // 64)
    return _scan_stretch(keys, (x, y), (width, height), plan,
                         (int(squares.j0[k]), int(squares.j1[k])), cap)


def _scan_stretch(keys: np.ndarray, origin: tuple[int, int], size: tuple[int, int],
                  plan: BlockPlan, blocks: tuple[int, int], cap: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Runs of blocks ``j .. j1-1`` of a ``(width, height)`` image (``blocks = (j, j1)``).

    ``keys`` is a window of the image with its top-left texel at ``origin``
    ``(x, y)`` that holds those blocks' texels; the run arrays start with room
    for ``cap`` runs. Returns ``(steps, values)`` as :func:`scan_runs`.
    """
    (x, y), (width, height), (j, j1) = origin, size, blocks
    steps, values = np.empty(cap, np.uint32), np.empty(cap, keys.dtype)
    # The stretch's first value, at its first texel inside the image.
    row, col = _first_texel(plan, j, (height, width))
    count, cur, last = 0, keys[row - y, col - x], np.uint64(0)
    while True:
        count, j, cur, last = _runs_kernel(keys, x, y, width, height, *plan_args(plan), j, j1,
                                           steps, values, count, cur, last)
        if j == j1:
            break
        # Out of room: double the run arrays and resume at block j, with the first call's
        # types (the kernel returns Python ints, which would compile new signatures).
        cur, last = keys.dtype.type(cur), np.uint64(last)
        steps = np.concatenate([steps, np.empty_like(steps)])
        values = np.concatenate([values, np.empty_like(values)])
    return (np.append(steps[:count], np.uint32(last)),
            np.append(values[:count], values.dtype.type(cur)))


def join_runs(parts: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Runs of consecutive stretches of a curve, stitched (a run cut in two is merged)."""
    steps = np.concatenate([p[0] for p in parts])
    values = np.concatenate([p[1] for p in parts])
    keep = np.append(values[1:] != values[:-1], True)
    return (steps, values) if keep.all() else (steps[keep], values[keep])


def ranks_to_steps(ends: np.ndarray, width: int, height: int, curve: str | Curve) -> np.ndarray:
    """(R,) uint32 0-based curve steps of the texels with 1-based ranks ``ends`` (<= W*H).

    Converts cumulative run lengths (the file's lengths) to the in-memory steps.
    """
    plan = block_plan(width, height, curve)
    ends = np.ascontiguousarray(ends, dtype=np.int64)
    out, done = _ranks_to_steps_kernel(ends, height, width, *plan_args(plan))
    if done != ends.size:
        raise TerrathemeError(f"run ends beyond the {width} x {height} image's texels")
    return out


def steps_to_ranks(steps: np.ndarray, width: int, height: int, curve: str | Curve) -> np.ndarray:
    """(R,) int64 1-based ranks of increasing steps; -1 where a step's block misses the image."""
    plan = block_plan(width, height, curve)
    steps = np.ascontiguousarray(steps, dtype=np.uint32)
    return _steps_to_ranks_kernel(steps, height, width, *plan_args(plan))


def check_run_ends(steps: np.ndarray, width: int, height: int, curve: str | Curve) -> None:
    """Check ``steps`` (R,) int64, the 0-based last steps of an image's runs along a curve:
    strictly increasing from 0 or more, each on an image texel, the last the image's last."""
    curve = Curve.parse(curve)
    if steps[0] < 0 or np.any(np.diff(steps) <= 0):
        raise TerrathemeError("run steps must be strictly increasing and non-negative")
    last = int(ranks_to_steps(np.array([width * height]), width, height, curve)[0])
    if steps[-1] != last:
        raise TerrathemeError(
            f"the last run ends at step {int(steps[-1])}, but the image's last texel "
            f"along the {curve.name.lower()} curve is step {last}"
        )
    # Every run must end on an image texel (round trip through ranks).
    ranks = steps_to_ranks(steps.astype(np.uint32), width, height, curve)
    if ranks.min() < 1 or not np.array_equal(
            ranks_to_steps(ranks, width, height, curve).astype(np.int64), steps):
        raise TerrathemeError("a run ends on a curve step outside the image")
