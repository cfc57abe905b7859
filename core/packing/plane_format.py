"""The plane payload (encoding 2, docs/formats.md): the layer coded as an image, 2-D context mixing.

The texels are coded, so every decision sees its two-dimensional neighbourhood, and the
runs are rebuilt by a scan. Segments (aligned curve squares, :data:`SEGMENT_BITS`) are
coded in curve order, so memory holds one segment; inside, 8 x 8 blocks flagged uniform
or coded texel by texel (:mod:`.plane_model`, :mod:`.mixing`). Bounded work: decoding
stops past the stream, past the declared runs, or past ``MAX_TEXELS_PER_BYTE * stream
bytes + TEXEL_ALLOWANCE`` texels; the encoder never writes a payload over that.
"""

from __future__ import annotations

import numpy as np
from terratheme.core.curves.fill import fill_square
from terratheme.core.curves.plan import curve_squares
from terratheme.core.curves.scan import join_runs, ranks_to_steps, scan_square, steps_to_ranks
from terratheme.core.curves.square import Curve
from terratheme.core.errors import CorruptFileError
from terratheme.core.packing.plane_model import BLOCK, MAX_USED, PlaneModel, code_segment
from terratheme.core.packing.range_coder import finish_encoder, start_decoder, start_encoder

#: log2 of the segment side.
SEGMENT_BITS = 10
#: Ceiling on texels coded one by one, per byte of stream, plus an allowance.
MAX_TEXELS_PER_BYTE = 64
TEXEL_ALLOWANCE = 1 << 16


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
        model = PlaneModel(used.size)
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
    """Inverse of :func:`encode_plane`: ``(lengths, indices)``, (runs,) int64 and uint8.

    Raises CorruptFileError for a damaged or hostile payload (the module's bounds).
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
    model = PlaneModel(n_used)
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
        # No more runs than the header declares, give or take one stitched run a segment.
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
