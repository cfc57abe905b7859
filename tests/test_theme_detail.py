"""core.themes.detail: a theme's fine contrast around mid-grey, scaled to the photo's."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.themes.detail import (
    DETAIL_CONTRAST,
    NEUTRAL,
    detail_texture,
    detail_themes,
)
from terratheme.core.themes.library import Theme, ThemeLibrary


def test_detail_of_a_flat_texture_is_mid_grey():
    flat = np.full((16, 16, 3), (10, 120, 250), np.uint8)
    assert np.all(detail_texture(flat) == NEUTRAL)


def test_detail_drops_a_slow_ramp_and_keeps_a_checkerboard_as_a_ratio():
    yy, xx = np.indices((64, 64))
    # One period of a cosine across the tile: coarse, tileable; a 1-texel checkerboard: fine.
    ramp = 128 + 60 * np.cos(2 * np.pi * xx / 64)
    board = 1 + 0.1 * ((xx + yy) % 2 * 2 - 1)
    tex = np.repeat((ramp * board)[:, :, None], 3, axis=2).round().astype(np.uint8)
    out = detail_texture(tex, sigma=3.0).astype(float)
    # The ramp's 120 grey levels swing is gone but for a few (a sigma-3 blur keeps
    # exp(-2 pi^2 3^2 / 64^2) = 96% of a 64-texel cosine) ...
    assert np.ptp(out.mean(axis=0)[:, 0]) < 8.0
    # ... the checkerboard's +-10% stays, around 128 (a sigma-3 blur removes it) ...
    assert abs(np.abs(out[:, :, 0] - NEUTRAL).mean() - 12.8) < 1.5
    # ... and a gain of 2 doubles it.
    twice = detail_texture(tex, sigma=3.0, gain=2.0).astype(float)
    assert abs(np.abs(twice[:, :, 0] - NEUTRAL).mean() - 25.6) < 3.0


def test_detail_texture_stays_tileable():
    from terratheme.core.themes.detail import MIP_FLAT

    rng = np.random.default_rng(0)
    tex = rng.integers(0, 256, (32, 32, 3), dtype=np.uint8)
    # Rolling by whole blocks then filtering equals filtering then rolling: the blur and
    # the block field wrap around.
    assert np.array_equal(detail_texture(np.roll(tex, 2 * MIP_FLAT, axis=1)),
                          np.roll(detail_texture(tex), 2 * MIP_FLAT, axis=1))


def test_detail_gain_brings_the_theme_to_the_photo_contrast():
    yy, xx = np.indices((32, 32))
    board = ((xx + yy) % 2 * 2 - 1).astype(float)
    theme = np.repeat((100 * (1 + 0.05 * board))[:, :, None], 3, axis=2).round()
    photo = np.repeat((200 * (1 + 0.10 * board))[:, :, None], 3, axis=2).round()
    lib = ThemeLibrary([Theme("a", (1, 2, 3), theme.astype(np.uint8)),
                        Theme("b", (1, 2, 3), theme.astype(np.uint8))])
    labels = np.zeros((32, 32), np.uint8)  # every pixel takes theme 0
    themes, gains = detail_themes(photo.astype(np.uint8), labels, lib)
    # The photo's checkerboard swings twice as far as the theme's, then DETAIL_CONTRAST more.
    assert gains[0] == pytest.approx(2.0 * DETAIL_CONTRAST, rel=0.1)
    assert gains[1] == 1.0  # no pixel takes it
    made = themes[0].texture
    assert np.array_equal(made, detail_texture(theme.astype(np.uint8), gain=gains[0]))
    # The made theme swings +-10% around its mean as the photo does, times DETAIL_CONTRAST.
    assert np.abs(made.astype(float) / NEUTRAL - 1).mean() == pytest.approx(
        0.1 * DETAIL_CONTRAST, rel=0.2)


def test_a_fragment_theme_reaches_at_most_the_fragment_contrast():
    from terratheme.core.themes.detail import (
        FRAGMENT_COHERENCE,
        FRAGMENT_CONTRAST,
        edge_coherence,
    )

    xx = np.indices((32, 32))[1]
    # Vertical stripes: one orientation only, a fragment theme of relative RMS 0.05.
    # Two texels wide, so a 4-texel block holds both signs: nothing at the map's scale.
    stripes = (xx // 2 % 2 * 2 - 1).astype(float)
    theme = np.repeat((100 * (1 + 0.05 * stripes))[:, :, None], 3, axis=2).round()
    assert edge_coherence(theme.astype(np.uint8)) > FRAGMENT_COHERENCE
    lib = ThemeLibrary([Theme("town", (1, 2, 3), theme.astype(np.uint8))])
    labels = np.zeros((32, 32), np.uint8)

    def gain(contrast: float) -> float:
        photo = np.repeat((200 * (1 + contrast * stripes))[:, :, None], 3, axis=2).round()
        return detail_themes(photo.astype(np.uint8), labels, lib)[1][0]

    # A calm photo (RMS 0.02): the class's contrast, 1.5 x 0.02 = 0.03, under the cap ...
    assert gain(0.02) == pytest.approx(DETAIL_CONTRAST * 0.02 / 0.05, rel=0.1)
    # ... a town's (0.4): the theme's 0.05 brought to the cap, not to 0.6.
    assert 0.02 * DETAIL_CONTRAST < FRAGMENT_CONTRAST < 0.4 * DETAIL_CONTRAST
    assert gain(0.4) == pytest.approx(FRAGMENT_CONTRAST / 0.05, rel=0.1)


def test_a_heavy_tailed_class_sets_its_grain_by_its_robust_amplitude():
    from terratheme.core.themes.detail import TAIL_CAP

    yy, xx = np.indices((70, 70))
    stripes = (xx // 2 % 2 * 2 - 1).astype(float)
    # A stripe theme of relative RMS 0.05 (its gain is linear in the class's contrast).
    theme = np.repeat((100 * (1 + 0.05 * stripes[:32, :32]))[:, :, None], 3, axis=2)
    lib = ThemeLibrary([Theme("road", (1, 2, 3), theme.round().astype(np.uint8))])
    labels = np.zeros((70, 70), np.uint8)
    # A calm class, +-2% ...
    calm = 100 * (1 + 0.02 * stripes)
    # ... and the same with one texel in 49 at +-50% (cars on a road): RMS 0.073.
    spiky = calm.copy()
    cars = (xx % 7 == 0) & (yy % 7 == 0)
    spiky[cars] = 100 * (1 + 0.5 * np.where((xx // 7 + yy // 7) % 2 == 0, 1, -1)[cars])

    def gain(photo: np.ndarray) -> float:
        rgb = np.repeat(photo[:, :, None], 3, axis=2).round().astype(np.uint8)
        return detail_themes(rgb, labels, lib)[1][0]

    assert gain(calm) == pytest.approx(DETAIL_CONTRAST * 0.02 / 0.05, rel=0.05)
    # Robust amplitude 1.4826 x 0.02 (the median |relative|), at most TAIL_CAP times it
    # (0.89 at 1.0), not the RMS's 2.2.
    capped = DETAIL_CONTRAST * TAIL_CAP * 1.4826 * 0.02 / 0.05
    assert gain(spiky) == pytest.approx(capped, rel=0.05)
    assert capped < DETAIL_CONTRAST * 0.07 / 0.05


def test_detail_themes_keep_names_and_colours_each_at_its_gain():
    xx = np.indices((32, 32))[1]
    stripes = (xx // 4 % 2 * 2 - 1).astype(float)
    rng = np.random.default_rng(3)
    grain = rng.integers(60, 200, (32, 32, 3)).astype(np.uint8)
    town = np.repeat((100 * (1 + 0.05 * stripes))[:, :, None], 3, axis=2).round()
    lib = ThemeLibrary([Theme("town", (1, 2, 3), town.astype(np.uint8)),
                        Theme("sand", (4, 5, 6), grain)])
    photo = rng.integers(0, 255, (32, 32, 3)).astype(np.uint8)
    labels = (np.indices((32, 32))[0] >= 16).astype(np.uint8)
    made, gains = detail_themes(photo, labels, lib)
    # A fragment theme (town) and a grain theme, each at its own gain.
    assert gains[0] != gains[1]
    for k, theme in enumerate(lib):
        assert made[k].name == theme.name and made[k].colour == theme.colour
        np.testing.assert_array_equal(made[k].texture,
                                      detail_texture(theme.texture, gain=gains[k]))


def test_even_detail_fills_a_flat_strip_of_a_tileable_texture():
    from terratheme.core.themes.detail import EVEN_RANGE, _relative, even_detail

    rng = np.random.default_rng(1)
    tex = rng.integers(80, 180, (128, 128, 3)).astype(np.uint8)
    tex[:, 24:40] = 128 + (tex[:, 24:40].astype(int) - 128) // 10  # a strip of a tenth the contrast

    def strip_share(rel):
        rms = np.sqrt((rel.mean(axis=2) ** 2).mean(axis=0))
        return rms[28:36].mean() / rms[:16].mean()

    plain = strip_share(_relative(tex, 3.0, wrap=True))
    evened = strip_share(even_detail(tex))
    # The strip's share of detail grows by most of the largest factor allowed ...
    assert plain < 0.15 and evened > 0.6 * EVEN_RANGE[1] * plain
    # ... and the rest keeps its pattern: evening only scales it.
    out = detail_texture(tex).astype(float) - NEUTRAL
    assert np.corrcoef(out[:, :16].ravel(), (tex[:, :16].astype(float) - 128).ravel())[0, 1] > 0.5


def _road_pieces(seed: int = 0) -> np.ndarray:
    """A 64 x 64 grey theme of 12 dark line pieces at random angles (a town theme's fragments)."""
    import cv2

    rng = np.random.default_rng(seed)
    img = np.full((64, 64), 150, np.uint8)
    for _ in range(12):
        x0, y0 = (int(v) for v in rng.integers(6, 58, 2))
        angle, length = rng.uniform(0, np.pi), int(rng.integers(15, 30))
        x1 = int(np.clip(x0 + length * np.cos(angle), 4, 60))
        y1 = int(np.clip(y0 + length * np.sin(angle), 4, 60))
        cv2.line(img, (x0, y0), (x1, y1), 60, 2)
    return np.repeat(img[:, :, None], 3, axis=2)


def test_edge_coherence_of_stripes_flat_and_grain():
    from terratheme.core.themes.detail import FRAGMENT_COHERENCE, edge_coherence

    xx = np.indices((64, 64))[1]
    stripes = np.repeat((128 + 40 * np.sin(2 * np.pi * xx / 8))[:, :, None], 3, axis=2)
    # Gradients all along x: the tensor's second eigenvalue is 0, the coherence 1.
    assert edge_coherence(stripes.round().astype(np.uint8)) == pytest.approx(1.0, abs=1e-4)
    assert edge_coherence(np.full((16, 16, 3), 90, np.uint8)) == 0.0
    grain = np.random.default_rng(0).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    assert edge_coherence(grain) < FRAGMENT_COHERENCE < edge_coherence(_road_pieces())


def test_a_fragment_theme_keeps_its_fine_energy_but_not_its_edges():
    from terratheme.core.themes.detail import (
        DETAIL_SIGMA,
        FRAGMENT_COHERENCE,
        _random_phases,
        edge_coherence,
        even_detail,
        theme_detail,
    )

    pieces = _road_pieces()
    rel, fragment = theme_detail(pieces)
    assert fragment
    # Random phases keep the power spectrum (Parseval): the energy of even_detail ...
    fine = even_detail(pieces, DETAIL_SIGMA)
    assert float((_random_phases(fine) ** 2).mean()) == pytest.approx(
        float((fine ** 2).mean()), rel=1e-4)
    # ... the theme's detail has lost the pieces' phases (uncorrelated with them), is flat
    # at the map's scale (its 4 x 4 blocks average to 0) and has at most their energy ...
    assert abs(float(np.corrcoef(rel.ravel(), fine.ravel())[0, 1])) < 0.1
    assert np.abs(rel.reshape(16, 4, 16, 4, 3).mean(axis=(1, 3))).max() < 1e-6
    assert 0.3 < float((rel ** 2).mean()) / float((fine ** 2).mean()) <= 1.0
    # The pieces' edges are gone (the old detail texture kept them: coherence 0.64) ...
    assert edge_coherence(detail_texture(pieces)) < FRAGMENT_COHERENCE
    # ... the result still tiles (random phases commute with a shift) ...
    assert np.allclose(theme_detail(np.roll(pieces, 8, axis=0))[0], np.roll(rel, 8, axis=0),
                       atol=1e-5)
    # ... and an isotropic grain theme keeps its phases: white noise around its mean, whose
    # relative detail at sigma 3 is close to g / mean(g) - 1 (the blur is nearly flat).
    grain = np.random.default_rng(0).integers(0, 256, (128, 128, 3), dtype=np.uint8)
    same, fragment = theme_detail(grain)
    g = grain.astype(float)
    assert not fragment and float(np.corrcoef(same.ravel(), (g / g.mean() - 1).ravel())[0, 1]) > 0.9


def test_a_small_theme_has_its_phases_randomised_at_its_own_contrast():
    from terratheme.core.themes.detail import LATTICE_SIDE, theme_detail

    def grain(side: int) -> np.ndarray:
        return np.random.default_rng(3).integers(0, 256, (side, side, 3), dtype=np.uint8)

    def relative(side: int) -> np.ndarray:
        # White noise around its mean: its relative detail at sigma 3 is about g / mean - 1,
        # of energy (1/3 - 1/4) / (1/4) = 1/3 for values uniform on 0..255.
        g = grain(side).astype(float)
        return g / g.mean() - 1

    def corr(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.corrcoef(a.ravel(), b.ravel())[0, 1])

    assert 64 < LATTICE_SIDE <= 128
    # A 64-texel theme repeats 4 times in 256: its texels are reshuffled in phase (no lattice
    # of its features), not a fragment (its gain stays), with its energy (less the 1/16 of
    # white noise at the 4 x 4 block scale).
    small, fragment = theme_detail(grain(64))
    assert not fragment and abs(corr(small, relative(64))) < 0.1
    assert float((small ** 2).mean()) == pytest.approx(1 / 3 * 15 / 16, rel=0.1)
    # A 128-texel one keeps its texels.
    large, fragment = theme_detail(grain(128))
    assert not fragment and corr(large, relative(128)) > 0.9

def test_mip_flat_blocks_average_to_zero_and_finer_content_stays():
    from terratheme.core.themes.detail import mip_flat

    yy, xx = np.indices((16, 16))
    # A 1-texel checkerboard averages to 0 over every 4 x 4 block: nothing to take off.
    board = np.repeat(((xx + yy) % 2 * 2 - 1.0)[:, :, None], 3, axis=2) * 0.1
    np.testing.assert_allclose(mip_flat(board), board, atol=1e-7)
    # A block-scale cosine (period 16) is the map's scale: taken off all but nothing
    # (the smooth field is bilinear, so a cosine's residue is second order).
    wave = np.repeat((0.2 * np.cos(2 * np.pi * xx / 16))[:, :, None], 3, axis=2)
    flat = mip_flat(wave + board)
    means = flat.reshape(4, 4, 4, 4, 3).mean(axis=(1, 3))
    assert np.abs(means).max() < 1e-6
    assert np.abs(flat - board).max() < 0.2 * 0.25


@pytest.mark.parametrize("shape, want", [((30, 45, 3), (32, 44, 3)), ((3, 5, 3), (4, 4, 3)),
                                         ((32, 40, 3), (32, 40, 3))])
def test_mip_flat_resamples_to_whole_blocks_and_stays_tileable(shape, want):
    from scipy.ndimage import gaussian_filter
    from terratheme.core.themes.detail import mip_flat

    rng = np.random.default_rng(1)
    rel = gaussian_filter(rng.standard_normal(shape), (1.0, 1.0, 0), mode="wrap")
    out = mip_flat(rel)
    assert out.shape == want and out.dtype == np.float32
    means = out.reshape(want[0] // 4, 4, want[1] // 4, 4, 3).mean(axis=(1, 3))
    assert np.abs(means).max() < 1e-6
    # Rolled by whole blocks, the same result rolled: the field wraps around.
    if shape[:2] == want[:2]:
        np.testing.assert_allclose(mip_flat(np.roll(rel, 4, axis=1)), np.roll(out, 4, axis=1),
                                   atol=1e-6)
