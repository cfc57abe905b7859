"""The plane payload's model (docs/formats.md, encoding 2): one numba kernel that codes and
decodes a segment (:func:`code_segment`), and its adaptive state (:class:`PlaneModel`).
"""

from __future__ import annotations

import numba
import numpy as np
from terratheme.core.packing.mixing import (
    COUNTER_INIT,
    counter_p12,
    counter_update,
    counter_x,
    mix,
    mix_update,
)
from terratheme.core.packing.range_coder import get_bit, put_bit

BLOCK = 8
#: Texel value meaning "not decoded yet" (so at most 254 classes are coded).
UNKNOWN = 255
MAX_USED = 254
#: Counter adaptation limit and mixer learning rate (tuned on the shared maps).
COUNTER_LIMIT = 127
MIX_RATE = 2
# Counter tables, end to end in one array: texel models 1-4, block models 1-2,
# candidate hits, segment flag, then the symbol trees.
_T1, _T2, _T3, _T4 = 0, 8192, 8192 + 16384, 8192 + 2 * 16384
_F1 = _T4 + 8192
_F2 = _F1 + 576
_C = _F2 + 4096
_SEG = _C + 6144
_SYM = _SEG + 4
TEXEL_INPUTS = 4


# Not inline="always": numba's inlining slows code_segment's compile; LLVM inlines it anyway.
@numba.njit(cache=True, nogil=True)
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


class PlaneModel:
    """The adaptive state both ends start from: counters, counts, mixer weights."""

    def __init__(self, n_used: int) -> None:
        self.depth = max(1, int(n_used - 1).bit_length())
        contexts = n_used * (n_used + 1) if n_used <= 16 else n_used
        self.pr = np.full(_SYM + (contexts << self.depth), COUNTER_INIT, np.int32)
        self.cn = np.zeros(self.pr.size, np.uint8)
        self.wt = np.full((64, TEXEL_INPUTS), 65536 // 3, np.int64)
        self.wf = np.full((16, 3), 65536 // 2, np.int64)
