"""Make the shipped theme library: ``themes/*.png`` + ``themes/themes.json``.

Run: ``.venv/bin/python themes/make_themes.py [--dubai ../shared/data/dubai]``

* Photo themes (sand, town, grass) are cut from the Dubai aerial
  photos (Humans in the Loop, CC0 1.0; see themes/README.md): for each class
  the script picks the window whose mask is purest for that class, then
  makes it tileable with :func:`core.themes.tileable.make_tileable` (default
  options: Moisan periodic-plus-smooth wrap, then periodic low-frequency
  flattening -- no cross-fade ghosts, no tile-sized banding). A window
  that holds a landmark (grass: a Y-shaped tidal channel) first has it
  filled from the rest of the window by shift-map inpainting
  (``cv2.xphoto.inpaint``, ``INPAINT_SHIFTMAP``: He & Sun 2012, patch
  offsets), so it does not repeat once per tile.
* Procedural themes (water, forest, crop field, rock, road, snow) are synthesised
  from spectrally filtered noise, which is periodic by construction (FFT),
  and periodic Gaussian filters (``mode="grid-wrap"``): seamless without a fade.
  They go through :func:`core.themes.tileable.make_tileable` too, which leaves a
  periodic texture's seam alone and only flattens its tile-sized blotches
  (1/f noise puts most of its energy in the lowest, tile-sized waves).

Everything is seeded, so a re-run reproduces the same files. Every theme
must pass :func:`core.themes.tileable.seam_score` and
:func:`core.themes.quality.lowfreq_score`, and every photo theme
:func:`core.themes.quality.repeat_score` (the script checks them).
"""

from __future__ import annotations

import argparse
import glob
import json
import sys
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from terratheme.core.io.atomic import write_bytes_atomic  # noqa: E402
from terratheme.core.io.images import read_image, write_image  # noqa: E402
from terratheme.core.themes.quality import (  # noqa: E402
    landmark_mask,
    landmark_score,
    lowfreq_score,
    repeat_score,
)
from terratheme.core.themes.tileable import SEAM_THRESHOLD, make_tileable, seam_score  # noqa: E402

SIZE = 256
#: banding pass mark: share of contrast in waves of <= 2 periods per tile
LOWFREQ_MAX = 0.2
#: ghost / copy pass mark for photo themes (a half-shift cross-fade scores about 0.85)
REPEAT_MAX = 0.3
#: largest landmark (core.themes.quality.landmark_score) a cleaned photo theme may keep
LANDMARK_MAX = 0.02
#: remove_landmarks: features smaller than this share of the window are texture grain
LANDMARK_MIN_AREA = 0.008
#: remove_landmarks: texels added around a feature so its soft edge goes too
LANDMARK_MARGIN = 4


def spectral_noise(rng: np.random.Generator, size: int, beta: float) -> np.ndarray:
    """(size, size) float periodic noise with a 1/f^beta spectrum, zero mean, unit std."""
    white = np.fft.fft2(rng.standard_normal((size, size)))
    f = np.hypot(*np.meshgrid(np.fft.fftfreq(size), np.fft.fftfreq(size)))
    f[0, 0] = 1.0
    out = np.real(np.fft.ifft2(white / f**beta))
    return (out - out.mean()) / out.std()


def colourise(v: np.ndarray, lo: tuple, hi: tuple) -> np.ndarray:
    """Map values in [0, 1] onto the colour ramp lo -> hi; (h, w, 3) float."""
    v = np.clip(v, 0, 1)[..., None]
    return np.asarray(lo, float) * (1 - v) + np.asarray(hi, float) * v


def to_u8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def forest(rng: np.random.Generator) -> np.ndarray:
    """Tree crowns: random bright discs with shadows on a dark canopy, wrapping."""
    crowns = np.zeros((SIZE, SIZE))
    yy, xx = np.mgrid[0:SIZE, 0:SIZE]
    for _ in range(260):
        cx, cy, r = rng.uniform(0, SIZE), rng.uniform(0, SIZE), rng.uniform(4, 9)
        dx = (xx - cx + SIZE / 2) % SIZE - SIZE / 2
        dy = (yy - cy + SIZE / 2) % SIZE - SIZE / 2
        d = np.hypot(dx + 0.35 * r, dy + 0.35 * r) / r  # lit from the top left
        crowns = np.maximum(crowns, np.clip(1 - d, 0, 1) ** 0.6 * rng.uniform(0.6, 1.0))
    fine = spectral_noise(rng, SIZE, 0.6)
    v = 0.15 + 0.75 * crowns + 0.06 * fine
    return to_u8(colourise(v, (12, 38, 18), (70, 130, 55)))


def crop_field(rng: np.random.Generator) -> np.ndarray:
    """Parallel crop rows (period divides the tile) with patchy ripeness."""
    yy = np.mgrid[0:SIZE, 0:SIZE][0]
    rows = 0.5 + 0.5 * np.cos(2 * np.pi * yy * 32 / SIZE)
    patch = spectral_noise(rng, SIZE, 1.8)
    fine = spectral_noise(rng, SIZE, 0.5)
    v = 0.45 + 0.25 * rows + 0.12 * patch + 0.05 * fine
    base = colourise(v, (95, 110, 40), (205, 190, 95))
    return to_u8(base)


def rock(rng: np.random.Generator) -> np.ndarray:
    """Grey fractal rock with darker cracks."""
    v = spectral_noise(rng, SIZE, 1.3)
    ridges = np.abs(spectral_noise(rng, SIZE, 1.6))
    cracks = np.clip(1 - ridges / 0.12, 0, 1)
    g = 0.5 + 0.14 * v + 0.05 * spectral_noise(rng, SIZE, 0.3) - 0.25 * cracks
    return to_u8(colourise(g, (40, 38, 36), (205, 200, 190)))


def road(rng: np.random.Generator) -> np.ndarray:
    """Asphalt: dark grey with fine aggregate and faint wear patches."""
    fine = spectral_noise(rng, SIZE, 0.2)
    wear = spectral_noise(rng, SIZE, 2.0)
    g = 0.45 + 0.08 * fine + 0.06 * wear
    return to_u8(colourise(g, (35, 36, 40), (140, 140, 145)))


def snow(rng: np.random.Generator) -> np.ndarray:
    """Wind-blown snow: bright blue-white with soft drifts."""
    drift = ndimage.gaussian_filter(spectral_noise(rng, SIZE, 1.5), (1, 6), mode="grid-wrap")
    g = 0.75 + 0.1 * drift / drift.std() + 0.02 * spectral_noise(rng, SIZE, 0.2)
    return to_u8(colourise(g, (150, 165, 190), (255, 255, 255)))


def _window_sums(a: np.ndarray, size: int) -> np.ndarray:
    """Sum of ``a`` over every ``size`` x ``size`` window, stepping by 8 (integral image)."""
    ii = np.pad(a.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    s = ii[size:, size:] - ii[:-size, size:] - ii[size:, :-size] + ii[:-size, :-size]
    return s[::8, ::8]


def best_window(
    dubai: Path, cls: int, size: int, greenness: float = 0.0
) -> tuple[np.ndarray, str, float]:
    """The photo window that is purest for mask class ``cls`` (plus a greenness bonus)."""
    best = (-np.inf, None, "", 0.0)
    for mpath in sorted(glob.glob(str(dubai / "masks" / "*.png"))):
        mask = read_image(mpath)[..., 0] == cls
        if mask.shape[0] < size or mask.shape[1] < size or mask.mean() < 0.05:
            continue
        frac = _window_sums(mask.astype(np.int64), size) / size**2
        score = frac.copy()
        if greenness:
            photo = read_image(_photo_of(mpath), dtype=np.uint8)[..., :3].astype(np.float64)
            excess = photo[..., 1] - 0.5 * (photo[..., 0] + photo[..., 2])
            # Among windows at least 90 % pure, prefer the greenest.
            score = np.where(frac >= 0.9, frac + greenness * _window_sums(excess, size) / size**2,
                             -np.inf)
        j, i = np.unravel_index(np.argmax(score), score.shape)
        if score[j, i] > best[0]:
            best = (float(score[j, i]), (j * 8, i * 8), mpath, float(frac[j, i]))
    _, (y, x), mpath, purity = best
    photo = _photo_of(mpath)
    img = read_image(photo, dtype=np.uint8)[y : y + size, x : x + size, :3]
    return img, f"{photo.name} x={x} y={y} {size}x{size}", purity


def remove_landmarks(patch: np.ndarray) -> tuple[np.ndarray, float]:
    """Fill a window's landmarks (channels, paths) from its own texture.

    Parameters
    ----------
    patch : (h, w, 3) uint8 ndarray

    Returns
    -------
    cleaned : (h, w, 3) uint8 ndarray
    share : float
        Share of the window that was filled.
    """
    # Dark and bright features wider than the grain (core.themes.quality.landmark_mask).
    hole = np.zeros(patch.shape[:2], np.uint8)
    for mask in landmark_mask(patch, periodic=False):
        _n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8))
        big = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= LANDMARK_MIN_AREA * mask.size)
        hole |= np.isin(labels, big[big > 0])
    # Grow each feature by its soft edge.
    side = 2 * LANDMARK_MARGIN + 1
    hole = cv2.dilate(hole, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side, side)))
    if not hole.any():
        return patch, 0.0
    # Shift-map inpainting in Lab (the mask is 1 where pixels are kept).
    lab = cv2.cvtColor(patch, cv2.COLOR_RGB2Lab)
    out = np.zeros_like(lab)
    cv2.xphoto.inpaint(lab, (1 - hole).astype(np.uint8), out, cv2.xphoto.INPAINT_SHIFTMAP)
    return cv2.cvtColor(out, cv2.COLOR_Lab2RGB), float(hole.mean())


def _photo_of(mask_path: str) -> Path:
    return Path(mask_path.replace("/masks/", "/images/")).with_suffix(".jpg")


def water(rng: np.random.Generator) -> np.ndarray:
    """Open water: deep blue with wind ripples and soft swell."""
    ripples = ndimage.gaussian_filter(spectral_noise(rng, SIZE, 0.8), (0.6, 2.5), mode="grid-wrap")
    swell = spectral_noise(rng, SIZE, 2.2)
    g = 0.45 + 0.12 * ripples / ripples.std() + 0.12 * swell
    return to_u8(colourise(g, (10, 35, 80), (70, 130, 185)))


PHOTO = [
    # name, mask class, greenness bonus, landmarks removed, display colour, description
    ("sand", 2, 0.0, True, (225, 200, 140), "bare land / desert sand (Dubai photo, made tileable)"),
    # Streets are what a town texture shows: they stay.
    ("town", 1, 0.0, False, (200, 60, 60), "buildings and roofs (Dubai photo, made tileable)"),
    ("grass", 4, 0.02, True, (120, 200, 80),
     "grass and low vegetation (Dubai photo, channel filled, made tileable)"),
]
PROCEDURAL = [
    ("water", water, (40, 90, 200), "open water (procedural)"),
    ("forest", forest, (20, 110, 40), "tree canopy (procedural)"),
    ("crop field", crop_field, (230, 210, 60), "crop rows (procedural)"),
    ("rock", rock, (130, 130, 130), "bare rock (procedural)"),
    ("road", road, (60, 60, 60), "asphalt (procedural)"),
    ("snow", snow, (240, 240, 250), "snow (procedural)"),
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dubai", default=str(HERE.parents[1] / "shared" / "data" / "dubai"))
    args = ap.parse_args()
    dubai = Path(args.dubai)
    entries, credits = [], []
    rng = np.random.default_rng(20261123)
    cleaned = set()
    for name, cls, green, clean, colour, desc in PHOTO:
        if not (dubai / "masks").is_dir():
            raise SystemExit(f"{dubai}: Dubai photos not found (needed for photo themes)")
        patch, where, purity = best_window(dubai, cls, SIZE, green)
        filled = 0.0
        if clean:
            patch, filled = remove_landmarks(patch)
            cleaned.add(name)
        tex = make_tileable(patch)
        entries.append((name, colour, tex, desc))
        note = f", {filled:.1%} filled by shift-map inpainting" if filled else ""
        credits.append(f"{name}: {where} (class purity {purity:.2f}{note})")
    photo_names = {entry[0] for entry in entries}
    for name, fn, colour, desc in PROCEDURAL:
        entries.append((name, colour, make_tileable(fn(rng)), desc))
    meta = []
    for name, colour, tex, desc in entries:
        score, low, rep = seam_score(tex), lowfreq_score(tex), repeat_score(tex)
        if score > SEAM_THRESHOLD:
            raise SystemExit(f"{name}: seam score {score:.2f} above {SEAM_THRESHOLD}")
        if low > LOWFREQ_MAX:
            raise SystemExit(f"{name}: low-frequency share {low:.2f} above {LOWFREQ_MAX}")
        if name in photo_names and rep > REPEAT_MAX:
            raise SystemExit(f"{name}: repeat score {rep:.2f} above {REPEAT_MAX}")
        mark = landmark_score(tex)
        if name in cleaned and mark > LANDMARK_MAX:
            raise SystemExit(f"{name}: landmark covers {mark:.3f} of the tile, "
                             f"above {LANDMARK_MAX}")
        file = name.replace(" ", "_") + ".png"
        write_image(HERE / file, tex)
        meta.append({"name": name, "colour": list(colour), "file": file, "description": desc})
        print(f"{name:12s} {file:16s} seam {score:.2f} lowfreq {low:.3f} repeat {rep:.3f} "
              f"landmark {mark:.4f}")
    text = json.dumps({"version": 1, "themes": meta}, indent=1) + "\n"
    write_bytes_atomic(HERE / "themes.json", text.encode())
    write_bytes_atomic(HERE / "photo_sources.txt", ("\n".join(credits) + "\n").encode())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
