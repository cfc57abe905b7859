"""The GPU render's tile geometry (pure arithmetic: no OpenGL context needed)."""

from __future__ import annotations

import pytest
from terratheme.core.gpu.plan import RenderMode, RenderPlan, tile_geometry
from terratheme.core.gpu.style import Style


def _plan(filtered: bool, region=(0, 0, 64, 64), out_size=(64, 64), tile=32) -> RenderPlan:
    mode = RenderMode(Style(False, None, None), filtered)
    return RenderPlan(None, None, (4, 4), (16, 16), (64, 64), region, out_size, mode, tile)


@pytest.mark.parametrize(("filtered", "cells"), [(False, (2, 0, 3, 1)), (True, (1, 0, 3, 2))])
def test_a_tile_covers_its_cells_and_the_filtered_path_one_more(filtered, cells):
    size, view, under = tile_geometry(_plan(filtered), 32, 0)
    assert size == (32, 32) and view == (32, 0, 32, 32) and under == cells


def test_the_last_tile_is_cut_to_the_output_and_scaled_views_follow_the_region():
    # A 40 x 40 output of the region (8, 8, 48, 48): 1.2 texels per pixel.
    size, view, under = tile_geometry(_plan(False, (8, 8, 48, 48), (40, 40)), 32, 32)
    assert size == (8, 8)
    assert view == pytest.approx((8 + 32 * 1.2, 8 + 32 * 1.2, 8 * 1.2, 8 * 1.2))
    assert under == (2, 2, 3, 3)
