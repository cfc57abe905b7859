"""How much a thematic texture looks like its photo: colour layout, fine detail, structure.

On whole images of the same size: :func:`colour_error` (``dE8``), :func:`detail_ratio`,
:func:`detail_placement` (per block) and :func:`structure_similarity` (``structure 1/4``,
``1/8``);
definitions in docs/design.md §5.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from skimage.color import deltaE_ciede2000, rgb2gray, rgb2lab
from skimage.metrics import structural_similarity
from terratheme.core.errors import TerrathemeError

#: blur of the colour-layout error, pixels
COLOUR_SIGMA = 8.0
#: the detail band: Gaussian sigmas (pixels) whose difference is the band-pass
DETAIL_SIGMAS = (0.7, 3.0)
#: side (pixels) of the blocks :func:`detail_placement` compares
PLACEMENT_BLOCK = 32
#: detail energy added to each block's by :func:`detail_placement` (luminance in [0, 1]:
#: a band-pass RMS of about 1.1 grey levels of 255)
PLACEMENT_FLOOR = 2e-5


def _rgb(image: np.ndarray, name: str) -> np.ndarray:
    """(H, W, 3) float32 in [0, 1] from an 8- or 16-bit RGB(A) image."""
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] not in (3, 4) or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise TerrathemeError(f"{name} must be an (H, W, 3) RGB image, got shape {arr.shape}")
    scale = 65535.0 if arr.dtype == np.uint16 else 255.0 if arr.dtype == np.uint8 else 1.0
    return np.ascontiguousarray(arr[:, :, :3], dtype=np.float32) / np.float32(scale)


@dataclass(frozen=True, eq=False)
class Reference:
    """A photo's side of :func:`colour_error` and :func:`structure_similarity`, computed
    once to compare many renders against it (:func:`reference`).

    ``rgb`` (H, W, 3) float32 in [0, 1]; ``lab``: {sigma: the photo blurred by sigma, in
    CIELAB (H, W, 3)}; ``gray``: {factor: its luminance downscaled by factor}.
    """

    rgb: np.ndarray
    lab: Mapping[float, np.ndarray]
    gray: Mapping[int, np.ndarray]


def reference(photo: np.ndarray, *, sigmas: Sequence[float] = (COLOUR_SIGMA,),
              factors: Sequence[int] = (4, 8)) -> Reference:
    """The photo prepared for :func:`colour_error` at each of ``sigmas`` and
    :func:`structure_similarity` at each of ``factors`` (others are computed per call)."""
    rgb = _rgb(photo, "photo")
    return Reference(rgb, {float(s): _blurred_lab(rgb, s) for s in sigmas},
                     {int(f): _small_gray(rgb, f) for f in factors})


def _blurred_lab(rgb: np.ndarray, sigma: float) -> np.ndarray:
    # Blur in sRGB (what the eye integrates at a distance), then CIELAB.
    return rgb2lab(cv2.GaussianBlur(rgb, (0, 0), sigma, borderType=cv2.BORDER_REFLECT))


def _small_gray(rgb: np.ndarray, factor: int) -> np.ndarray:
    """Luminance after a ``factor`` x area downscaling: the means of whole ``factor`` x
    ``factor`` blocks from the top-left, the last part-blocks left out (a texture's mip level
    sees the same blocks; a fractional ratio would straddle them). Sides of fewer than 7
    blocks are resized to 7."""
    f = int(factor)
    h, w = rgb.shape[:2]
    gray = rgb2gray(rgb).astype(np.float32)
    if w // f >= 7 and h // f >= 7:
        gray = gray[: h // f * f, : w // f * f]
    size = (max(7, w // f), max(7, h // f))
    return cv2.resize(gray, size, interpolation=cv2.INTER_AREA)


def _pair(render: np.ndarray, photo: np.ndarray | Reference) -> tuple[np.ndarray, np.ndarray]:
    r = _rgb(render, "render")
    p = photo.rgb if isinstance(photo, Reference) else _rgb(photo, "photo")
    if r.shape != p.shape:
        raise TerrathemeError(
            f"render is {r.shape[1]} x {r.shape[0]} but the photo is {p.shape[1]} x {p.shape[0]}"
        )
    return r, p


def _mask(valid: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray | None:
    if valid is None:
        return None
    v = np.asarray(valid, bool)
    if v.shape != shape[:2]:
        raise TerrathemeError(f"valid mask is {v.shape} but the images are {shape[:2]}")
    if not v.any():
        raise TerrathemeError("valid mask selects no pixel")
    return v


def colour_error(render: np.ndarray, photo: np.ndarray | Reference, *,
                 sigma: float = COLOUR_SIGMA, valid: np.ndarray | None = None) -> float:
    """Mean CIEDE2000 (``dE8``) between render and photo, both blurred by ``sigma`` px first.

    ``render, photo`` (H, W, 3) sRGB, uint8/uint16 or float in [0, 1], or the photo's
    :func:`reference`; ``valid`` (H, W) bool picks the pixels averaged. About 1: barely
    visible; above 10: clearly another colour.
    """
    r, p = _pair(render, photo)
    v = _mask(valid, r.shape)
    lab = photo.lab.get(float(sigma)) if isinstance(photo, Reference) else None
    de = deltaE_ciede2000(_blurred_lab(p, sigma) if lab is None else lab,
                          _blurred_lab(r, sigma))
    return float(de.mean() if v is None else de[v].mean())


def _band(rgb: np.ndarray, sigmas: tuple[float, float] = DETAIL_SIGMAS) -> np.ndarray:
    """(H, W) float32: the luminance band-pass ``G(sigma0) - G(sigma1)`` of (H, W, 3) RGB."""
    y = rgb2gray(rgb).astype(np.float32)
    fine = cv2.GaussianBlur(y, (0, 0), sigmas[0], borderType=cv2.BORDER_REFLECT)
    return fine - cv2.GaussianBlur(y, (0, 0), sigmas[1], borderType=cv2.BORDER_REFLECT)


def detail_energy(image: np.ndarray, *, sigmas: tuple[float, float] = DETAIL_SIGMAS,
                  valid: np.ndarray | None = None) -> float:
    """Mean square of the luminance band-pass ``G(sigma0) - G(sigma1)``, luminance in [0, 1]."""
    band = _band(_rgb(image, "image"), sigmas) ** 2
    v = _mask(valid, band.shape)
    return float(band.mean() if v is None else band[v].mean())


def detail_ratio(render: np.ndarray, photo: np.ndarray, *,
                 valid: np.ndarray | None = None) -> float:
    """The render's band-pass energy over the photo's (1 = as much fine texture)."""
    r, p = _pair(render, photo)
    ref = detail_energy(p, valid=valid)
    if ref <= 1e-12:
        raise TerrathemeError("the photo has no detail (flat): the detail ratio is undefined")
    return detail_energy(r, valid=valid) / ref


def detail_placement(render: np.ndarray, photo: np.ndarray, *, block: int = PLACEMENT_BLOCK,
                     floor: float = PLACEMENT_FLOOR) -> np.ndarray:
    """(H // block, W // block) float32: log2 of the render's detail energy over the photo's
    in each whole ``block`` x ``block`` block from the top-left (0: the photo's fine texture
    there, at its strength; +1: twice its energy).

    The energy is :func:`detail_energy`'s band, each block's mean plus ``floor`` (a flat
    block's ratio is 1, not noise over nothing). What a close view sees where
    :func:`detail_ratio` sums the whole image: a calm shore carrying a town's grain and a
    town carrying none can average to 1 there, but not here.
    """
    r, p = _pair(render, photo)
    b = int(block)
    h, w = r.shape[0] // b * b, r.shape[1] // b * b
    if h == 0 or w == 0:
        raise TerrathemeError(f"the images are smaller than one {b} x {b} block")

    def energies(rgb: np.ndarray) -> np.ndarray:
        band = _band(rgb[:h, :w]) ** 2
        return band.reshape(h // b, b, w // b, b).mean(axis=(1, 3)) + np.float32(floor)

    return np.log2(energies(r) / energies(p)).astype(np.float32)


def structure_similarity(render: np.ndarray, photo: np.ndarray | Reference,
                         factor: int = 4) -> float:
    """Mean SSIM (1: the same picture) of the luminance after ``factor`` x area downscaling.

    Whole blocks from the top-left (sides rounded down), at least 7 pixels a side;
    ``photo`` may be its :func:`reference`.
    """
    r, p = _pair(render, photo)
    small = photo.gray.get(int(factor)) if isinstance(photo, Reference) else None
    return float(structural_similarity(_small_gray(r, factor),
                                       _small_gray(p, factor) if small is None else small,
                                       data_range=1.0))


@dataclass(frozen=True)
class Fidelity:
    """The look of a render against its photo: ``colour_error`` (``dE8``) and ``detail``
    (:func:`detail_ratio`, NaN for a flat photo)."""

    colour_error: float
    detail: float

    def describe(self) -> str:
        """One line for a status bar: ``dE8 2.1, detail 0.93``."""
        detail = "n/a (flat photo)" if np.isnan(self.detail) else f"{self.detail:.2f}"
        return f"dE8 {self.colour_error:.1f}, detail {detail}"


def fidelity(render: np.ndarray, photo: np.ndarray) -> Fidelity:
    """:func:`colour_error` and :func:`detail_ratio` of a render against its photo."""
    try:
        detail = detail_ratio(render, photo)
    except TerrathemeError:
        detail = float("nan")
    return Fidelity(colour_error(render, photo), detail)
