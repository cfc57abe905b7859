"""The plane payload (encoding 2, file version 2): the layer coded as an image, 2-D context mixing.

The compact run streams (encoding 1) see each run along the curve with 1-D
context only. Here the texels themselves are coded, so every decision sees
its two-dimensional neighbourhood (issue 19), and the runs are rebuilt by a
scan afterwards:

* the layer is cut into the curve's aligned **segments** of ``2^g`` texels a
  side (``g`` = :data:`SEGMENT_BITS`), coded in curve order; a segment is a
  contiguous stretch of the curve, so each decoded segment is scanned into
  its runs at once (:func:`core.curves.scan.scan_square`) and memory holds
  one segment (1 MiB), not the layer. Contexts stay inside a segment; the
  models carry over from one segment to the next;
* a whole segment equal to the previous segment's last texel costs one
  decision (per-segment choice: skip or code);
* inside a segment, **8 x 8 blocks** in raster order: one decision says
  whether the block is uniform in its reference class (the texel left of
  it, else above it), predicted from how many texels along its top and left
  borders differ from that class and whether the blocks above and to the left
  were uniform (per-block choice: skip or code); most blocks are (89% of
  DRCOG's, 95% of ESA's);
* the texels of the other blocks, in raster order: ``v != r`` (``r`` = the
  left texel, else the one above) from four context models over the
  equality pattern of ten causal neighbours (N, NW, NE, WW, NN, NNE, NWW,
  NEE, NNW, NNEE) with ``r``, six equalities among them, ``r`` itself, and
  whether NE and W are known yet, mixed by a logistic mixer
  (:mod:`.mixing`); then whether ``v`` is one of the first three distinct
  neighbour classes, and failing that ``v`` down a binary tree in the
  context of ``r`` (and of the first candidate when few classes are used).

Every decision is coded with the range coder of :mod:`.range_coder`. Layout::

    u8   U - 1: number of palette indices used (U <= 254)
    U    the used indices, increasing (texels are coded as ranks in this list)
    u8   g, log2 of the segment side: SEGMENT_BITS (10), or the layer's own
         curve levels when smaller; any other value is refused
    ...  the range-coded decisions, to the end of the payload

Bounded work (checked while decoding, so a hostile payload ends at once):
the decoder stops when it reads past its stream, when a segment would add
more runs than the header declares, and after
``MAX_TEXELS_PER_BYTE * stream bytes + TEXEL_ALLOWANCE`` texels coded one by
one (real maps: 20-30 per byte), so a hostile payload costs at most about
what a real one of its size costs; the encoder never writes a payload over
the ceiling (the container then keeps the run streams).
"""

from __future__ import annotations

import numba
import numpy as np

from core.curves.fill import fill_square
from core.curves.plan import curve_squares
from core.curves.scan import join_runs, ranks_to_steps, scan_square, steps_to_ranks
from core.curves.square import Curve
from core.errors import CorruptFileError
from core.packing.mixing import (
    COUNTER_INIT,
    counter_p12,
    counter_update,
    counter_x,
    mix,
    mix_update,
)
from core.packing.range_coder import finish_encoder, get_bit, put_bit, start_decoder, start_encoder

#: log2 of the segment side.
SEGMENT_BITS = 10
BLOCK = 8
#: Texel value meaning "not decoded yet" (so at most 254 classes are coded).
UNKNOWN = 255
MAX_USED = 254
#: Counter adaptation limit and mixer learning rate (tuned on the shared maps).
COUNTER_LIMIT = 127
MIX_RATE = 2
#: Ceiling on texels coded one by one, per byte of stream, plus an allowance.
MAX_TEXELS_PER_BYTE = 64
TEXEL_ALLOWANCE = 1 << 16
# Counter tables, end to end in one array: texel models 1-4, block models 1-2,
# candidate hits, segment flag, then the symbol trees.
_T1, _T2, _T3, _T4 = 0, 8192, 8192 + 16384, 8192 + 2 * 16384
_F1 = _T4 + 8192
_F2 = _F1 + 576
_C = _F2 + 4096
_SEG = _C + 6144
_SYM = _SEG + 4
TEXEL_INPUTS = 4


@numba.njit(cache=True, nogil=True, inline="always")
def _code(dec, st, ds, buf, p1, bit):  # pragma: no cover - numba
    # Code (or decode) one bit with P(1) = p1 / 4096.
    p0 = (4096 - p1) << 3
    if dec:
        return get_bit(ds, buf, p0)
    put_bit(st, buf, p0, bit)
    return bit


@numba.njit(cache=True, nogil=True)
def code_segment(dec, img, pad, flags, rh, rw, full, seg_ref, last, n_used, depth, st, ds, buf,
                 pr, cn, wt, wf, budget):  # pragma: no cover - numba
    """Code (``dec`` False) or decode one segment of ``rh x rw`` texels.

    ``img`` holds the segment's ranks when encoding; the texels end up in
    ``pad[2:2 + rh, 2:2 + rw]`` either way (``pad`` has two unknown rows
    above and two unknown columns on each side). Returns ``(uniform, last,
    coded, error)``: whether the segment was the one-decision uniform kind,
    the class of its last texel in coding order, the texels coded one by one,
    and 0, 1 (read past the stream), 2 (impossible symbol) or 3 (over budget).
    """
    coded = 0
    if full:
        # A whole segment in the previous segment's last class: one decision.
        u = 0
        if not dec:
            u = 1
            for yy in range(rh):
                for xx in range(rw):
                    if img[yy, xx] != seg_ref:
                        u = 0
        u = _code(dec, st, ds, buf, counter_p12(pr, _SEG), u)
        counter_update(pr, cn, _SEG, u, COUNTER_LIMIT)
        if u:
            return 1, seg_ref, 0, 0
    pad[: rh + 2, : rw + 4] = UNKNOWN
    flags[: (rh + 7) // 8 + 1, : (rw + 7) // 8 + 1] = 0
    xf = np.zeros(3, np.int64)
    x = np.zeros(TEXEL_INPUTS, np.int64)
    cand = np.zeros(12, np.int64)
    for by in range(0, rh, BLOCK):
        for bx in range(0, rw, BLOCK):
            bh = min(BLOCK, rh - by)
            bw = min(BLOCK, rw - bx)
            y0 = by + 2
            x0 = bx + 2
            # The block's reference class: left of its first texel, else above, else last.
            ref = np.int64(pad[y0, x0 - 1])
            if ref == UNKNOWN:
                ref = np.int64(pad[y0 - 1, x0])
            if ref == UNKNOWN:
                ref = last
            # Known border texels that differ from it, along the top and the left.
            td = 0
            tk = 0
            for xx in range(x0 - 1, x0 + bw + 1):
                u = pad[y0 - 1, xx]
                if u != UNKNOWN:
                    tk += 1
                    td += u != ref
            ld = 0
            lk = 0
            for yy in range(y0, y0 + bh):
                u = pad[yy, x0 - 1]
                if u != UNKNOWN:
                    lk += 1
                    ld += u != ref
            uni = 0
            if not dec:
                uni = 1
                for yy in range(bh):
                    for xx in range(bw):
                        if img[by + yy, bx + xx] != ref:
                            uni = 0
            fa = flags[by // 8, bx // 8 + 1]
            fl = flags[by // 8 + 1, bx // 8]
            tdq = min(td, 3)
            ldq = min(ld, 3)
            c1 = _F1 + ((((tdq * 4 + ldq) * 2 + (tk > 0)) * 2 + (lk > 0)) * 3 + fa) * 3 + fl
            c2 = _F2 + (tdq * 4 + ldq) * 256 + ref
            xf[0] = counter_x(pr, c1)
            xf[1] = counter_x(pr, c2)
            xf[2] = 256
            ms = tdq * 4 + ldq
            p = mix(wf, ms, xf, 3)
            uni = _code(dec, st, ds, buf, p, uni)
            mix_update(wf, ms, xf, 3, p, uni, MIX_RATE)
            counter_update(pr, cn, c1, uni, COUNTER_LIMIT)
            counter_update(pr, cn, c2, uni, COUNTER_LIMIT)
            flags[by // 8 + 1, bx // 8 + 1] = 2 - uni
            if uni:
                pad[y0: y0 + bh, x0: x0 + bw] = ref
                last = ref
                continue
            for yy in range(bh):
                for xx in range(bw):
                    coded += 1
                    yc = y0 + yy
                    xc = x0 + xx
                    w_ = pad[yc, xc - 1]
                    n_ = pad[yc - 1, xc]
                    nw = pad[yc - 1, xc - 1]
                    ne = pad[yc - 1, xc + 1]
                    ww = pad[yc, xc - 2]
                    nn = pad[yc - 2, xc]
                    nne = pad[yc - 2, xc + 1]
                    nww = pad[yc - 1, xc - 2]
                    nee = pad[yc - 1, xc + 2]
                    nnw = pad[yc - 2, xc - 1]
                    nnee = pad[yc - 2, xc + 2]
                    r = np.int64(w_)
                    if r == UNKNOWN:
                        r = np.int64(n_)
                    if r == UNKNOWN:
                        r = last
                    # Which neighbours equal r, and how the upper ones relate.
                    e = np.int64(0)
                    for u in (n_, nw, ne, ww, nn, nne, nww, nee, nnw, nnee):
                        e = (e << 1) | (1 if u == r else 0)
                    rr = np.int64(0)
                    for a, c in ((n_, ne), (n_, nw), (ne, nne), (ne, nee), (n_, nn), (nw, nww)):
                        rr = (rr << 1) | (1 if a == c else 0)
                    kb = 1 if ne == UNKNOWN else 0
                    wk = 1 if w_ == UNKNOWN else 0
                    v = r
                    bit = 0
                    if not dec:
                        v = np.int64(img[by + yy, bx + xx])
                        bit = 1 if v != r else 0
                    t1 = _T1 + e * 8 + (kb * 2 + wk) * 2 + (1 if yy == 0 else 0)
                    t2 = _T2 + ((e >> 4) * 64 + rr) * 4 + kb * 2 + wk
                    t3 = _T3 + ((e >> 5) * 256 + r) * 2 + kb
                    t4 = _T4 + ((e & 0x3F) * 64 + rr) * 2 + kb
                    x[0] = counter_x(pr, t1)
                    x[1] = counter_x(pr, t2)
                    x[2] = counter_x(pr, t3)
                    x[3] = counter_x(pr, t4)
                    ms = (e >> 6) * 4 + kb * 2 + wk
                    p = mix(wt, ms, x, TEXEL_INPUTS)
                    bit = _code(dec, st, ds, buf, p, bit)
                    mix_update(wt, ms, x, TEXEL_INPUTS, p, bit, MIX_RATE)
                    counter_update(pr, cn, t1, bit, COUNTER_LIMIT)
                    counter_update(pr, cn, t2, bit, COUNTER_LIMIT)
                    counter_update(pr, cn, t3, bit, COUNTER_LIMIT)
                    counter_update(pr, cn, t4, bit, COUNTER_LIMIT)
                    if bit:
                        # The distinct known neighbour classes other than r, nearest first.
                        nc = 0
                        for u in (n_, ne, nw, ww, nn, nne, nee, nww, nnw, nnee):
                            if u != UNKNOWN and u != r:
                                dup = False
                                for q in range(nc):
                                    if cand[q] == u:
                                        dup = True
                                if not dup:
                                    cand[nc] = u
                                    nc += 1
                        found = False
                        for q in range(min(nc, 3)):
                            cc = _C + (q * 1024 + e) * 2 + kb
                            hit = _code(dec, st, ds, buf, counter_p12(pr, cc),
                                        1 if v == cand[q] else 0)
                            counter_update(pr, cn, cc, hit, COUNTER_LIMIT)
                            if hit:
                                v = cand[q]
                                found = True
                                break
                        if not found:
                            # The class itself, down a binary tree.
                            sctx = r
                            if n_used <= 16:
                                sctx = r * (n_used + 1) + (cand[0] if nc > 0 else n_used)
                            base = _SYM + (sctx << depth)
                            node = 1
                            for b in range(depth - 1, -1, -1):
                                bt = _code(dec, st, ds, buf, counter_p12(pr, base + node),
                                           (v >> b) & 1)
                                counter_update(pr, cn, base + node, bt, COUNTER_LIMIT)
                                node = node * 2 + bt
                            v = node - (1 << depth)
                            if v >= n_used:
                                return 0, last, coded, 2
                    pad[yc, xc] = v
                    last = v
            if dec and ds[2] > buf.size + 8:
                return 0, last, coded, 1
            if coded > budget:
                return 0, last, coded, 3
    return 0, last, coded, 0


class _Model:
    """The adaptive state both ends start from: counters, counts, mixer weights."""

    def __init__(self, n_used: int) -> None:
        self.depth = max(1, int(n_used - 1).bit_length())
        contexts = n_used * (n_used + 1) if n_used <= 16 else n_used
        self.pr = np.full(_SYM + (contexts << self.depth), COUNTER_INIT, np.int32)
        self.cn = np.zeros(self.pr.size, np.uint8)
        self.wt = np.full((64, TEXEL_INPUTS), 65536 // 3, np.int64)
        self.wf = np.full((16, 3), 65536 // 2, np.int64)


def can_code(indices: np.ndarray) -> bool:
    """Whether a layer's runs use few enough palette indices for this payload (<= 254)."""
    return np.unique(indices).size <= MAX_USED


def encode_plane(width: int, height: int, curve: int, lengths: np.ndarray,
                 indices: np.ndarray) -> bytes | None:
    """The plane payload of a layer's runs, or None when it would pass the texel ceiling."""
    curve = Curve(curve)
    used = np.unique(indices)
    rank = np.zeros(256, np.uint8)
    rank[used] = np.arange(used.size)
    steps = ranks_to_steps(np.cumsum(lengths), width, height, curve)
    values = rank[np.asarray(indices, np.uint8)]
    squares = curve_squares(width, height, curve, SEGMENT_BITS)
    side = 1 << squares.g
    head = bytes([used.size - 1]) + used.astype(np.uint8).tobytes() + bytes([squares.g])
    cap = 4 * lengths.size + 4096
    while True:
        model = _Model(used.size)
        pad = np.empty((side + 2, side + 4), np.uint8)
        flags = np.zeros((side // BLOCK + 2, side // BLOCK + 2), np.uint8)
        out = np.empty(cap, np.uint8)
        st, ds = start_encoder(), np.zeros(3, np.uint64)
        last = seg_ref = 0
        coded = 0
        for k in range(squares.sx.size):
            _, _, sw, sh = squares.rect(k, width, height)
            seg = fill_square(steps, values, width, height, curve, squares, k)
            _, last, n, _ = code_segment(False, seg, pad, flags, sh, sw, sw == sh == side,
                                         seg_ref, last, used.size, model.depth, st, ds, out,
                                         model.pr, model.cn, model.wt, model.wf, 1 << 62)
            coded += n
            seg_ref = last
        size, over = finish_encoder(st, out)
        if not over:
            break
        cap *= 4
    if coded > MAX_TEXELS_PER_BYTE * int(size) + TEXEL_ALLOWANCE:
        return None
    return head + out[: int(size)].tobytes()


def decode_plane(payload: bytes, width: int, height: int, curve: int, runs: int, *,
                 name: str) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`encode_plane`.

    Returns
    -------
    lengths : (runs,) int64 ndarray
    indices : (runs,) uint8 ndarray

    Raises
    ------
    CorruptFileError
        A damaged or hostile payload (see the module docstring's bounds).
    """
    if len(payload) < 2 or payload[0] + 1 > MAX_USED or len(payload) < payload[0] + 3:
        raise CorruptFileError(f"{name}: truncated or impossible plane payload header")
    n_used = payload[0] + 1
    used = np.frombuffer(payload, np.uint8, count=n_used, offset=1)
    g = payload[1 + n_used]
    curve = Curve(curve)
    squares = curve_squares(width, height, curve, SEGMENT_BITS)
    if np.any(np.diff(used.astype(int)) <= 0) or g != squares.g:
        raise CorruptFileError(f"{name}: bad plane payload header")
    side = 1 << squares.g
    # A writable copy: the one kernel that codes and decodes is typed for writable buffers.
    buf = np.frombuffer(payload, np.uint8, offset=2 + n_used).copy()
    budget = MAX_TEXELS_PER_BYTE * buf.size + TEXEL_ALLOWANCE
    model = _Model(n_used)
    pad = np.empty((side + 2, side + 4), np.uint8)
    flags = np.zeros((side // BLOCK + 2, side // BLOCK + 2), np.uint8)
    ds = start_decoder(buf)
    st = np.zeros(6, np.uint64)
    dummy = np.zeros((1, 1), np.uint8)
    last = seg_ref = 0
    parts, found = [], 0
    for k in range(squares.sx.size):
        _, _, sw, sh = squares.rect(k, width, height)
        uniform, last, coded, err = code_segment(True, dummy, pad, flags, sh, sw,
                                                 sw == sh == side, seg_ref, last, n_used,
                                                 model.depth, st, ds, buf, model.pr, model.cn,
                                                 model.wt, model.wf, budget)
        if err == 1 or ds[2] > buf.size + 8:
            raise CorruptFileError(f"{name}: plane stream ends inside segment {k}")
        if err == 2:
            raise CorruptFileError(f"{name}: impossible class in segment {k}")
        if err == 3:
            raise CorruptFileError(f"{name}: plane stream codes more texels than its "
                                   f"{buf.size} bytes may ({MAX_TEXELS_PER_BYTE} per byte)")
        budget -= coded
        if uniform:
            end = squares.first_step[k] + np.uint64(side * side - 1)
            parts.append((np.array([end], np.uint32), np.array([last], np.uint8)))
        else:
            parts.append(scan_square(pad[2: 2 + sh, 2: 2 + sw], width, height, curve,
                                     squares, k))
        found += parts[-1][0].size
        if found > runs + k + 1:
            raise CorruptFileError(f"{name}: plane stream holds more than the {runs} runs "
                                   "its header declares")
        seg_ref = last
    steps, values = join_runs(parts)
    if steps.size != runs:
        raise CorruptFileError(f"{name}: plane stream holds {steps.size} runs, the header "
                               f"declares {runs}")
    ends = steps_to_ranks(steps, width, height, curve)
    return np.diff(ends, prepend=0), used[values]
