"""Photo-wide strided samples (core.classify.tiled): every tiling draws the same pixels."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.classify.features import FeatureOptions
from terratheme.core.classify.prior import photo_probabilities
from terratheme.core.classify.tiled import feature_windows, sampling_stride, strided_pixels


def test_sampling_stride_known_answers():
    assert sampling_stride(100, 100, 1, 10_000) == 1
    assert sampling_stride(100, 100, 1, 2_500) == 2
    assert sampling_stride(101, 100, 1, 2_500) == 3  # 10100 coarse pixels: 2 would keep 2601
    assert sampling_stride(400, 400, 4, 2_500) == 2  # 100 x 100 coarse pixels
    assert sampling_stride(5, 5, 8, 10) == 1


@settings(max_examples=60, deadline=None)
@given(h=st.integers(1, 70), w=st.integers(1, 70), scale=st.sampled_from([1, 2, 4, 8]),
       tile=st.integers(1, 5), halo=st.integers(0, 3), stride=st.integers(1, 5),
       holes=st.booleans(), seed=st.integers(0, 1000))
def test_tiles_sample_the_photo_grid_pixels_with_data(h, w, scale, tile, halo, stride, holes,
                                                       seed):
    valid = np.random.default_rng(seed).random((h, w)) < 0.05 if holes else None
    ch, cw = -(-h // scale), -(-w // scale)
    # Every stride-th coarse row and column, where a photo pixel of the block has data.
    want = [(r, c) for r in range(0, ch, stride) for c in range(0, cw, stride)
            if valid is None or valid[r * scale:(r + 1) * scale, c * scale:(c + 1) * scale].any()]
    ids = np.arange(ch * cw).reshape(ch, cw)
    got = []
    for win in feature_windows(h, w, tile * scale, scale, halo):
        part = None if valid is None else valid[win.y:win.y1, win.x:win.x1]
        iy, ix, rows, cols = strided_pixels(win, scale, stride, part)
        # (iy, ix) index the read rectangle's coarse arrays at the same pixels, row-major.
        read = ids[win.ry // scale:-(-win.ry1 // scale), win.rx // scale:-(-win.rx1 // scale)]
        assert np.array_equal(read[iy, ix], rows * cw + cols)
        assert np.all(np.diff(rows * cw + cols) > 0)
        got += list(zip(rows.tolist(), cols.tolist(), strict=True))
    assert sorted(got) == want


def test_prior_samples_keep_to_the_budget_and_take_blocks_with_any_data():
    rgb = np.random.default_rng(3).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    fo = FeatureOptions(scale=4)

    def votes(feats):
        return np.ones((*feats.shape[:2], 2), np.float32)

    # 16 x 16 coarse pixels, at most 70: every 2nd row and column (a stride of 1 kept 256).
    assert len(photo_probabilities(rgb, None, votes, fo, 32, max_samples=70)) == 64
    # Data in photo column 1 only: coarse column 0 has it, though not in its first pixel.
    valid = np.zeros((64, 64), bool)
    valid[:, 1] = True
    assert len(photo_probabilities(rgb, valid, votes, fo, 32, max_samples=70)) == 8
