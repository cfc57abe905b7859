"""A scan with more runs than its first guess resumes with bigger arrays, with the same types."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.curves.fill import fill_runs
from terratheme.core.curves.scan import _runs_kernel, scan_runs


@pytest.mark.parametrize("dtype", [np.uint8, np.uint32])
@pytest.mark.parametrize("curve", ["hilbert", "morton"])
def test_noise_scans_resume_to_the_same_runs_and_signature(dtype, curve):
    # About one run a texel: the first guess (8192 runs, 64 x 64 blocks) is doubled twice.
    img = np.random.default_rng(3).integers(0, 250, (140, 150)).astype(dtype)
    img[:, 64] = 7                                  # and a run along the curve somewhere
    steps, values = scan_runs(img, curve)
    assert 16_384 < steps.size < img.size
    assert (np.diff(steps.astype(np.int64)) > 0).all() and (values[1:] != values[:-1]).all()
    assert values.dtype == dtype and steps.dtype == np.uint32
    # (filled as uint8: the values are below 250, and a layer fills palette indices)
    np.testing.assert_array_equal(fill_runs(steps, values.astype(np.uint8), 150, 140, curve), img)
    # Every resume passed the first call's types: one signature per key type, the run's
    # value in it and its step a uint64 (a resume with Python ints added two, one float64).
    tails = {tuple(str(t) for t in sig[-2:]) for sig in _runs_kernel.signatures
             if str(sig[0].dtype) == np.dtype(dtype).name}
    assert tails == {(np.dtype(dtype).name, "uint64")}
