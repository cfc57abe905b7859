"""Learned patch words (Coates & Ng 2011): k-means on whitened lightness patches.

Coates & Ng (2011), "The importance of encoding versus training with sparse
coding and vector quantization": a dictionary of K centroids learned by
k-means on contrast-normalised, ZCA-whitened image patches, and each patch
encoded by the "triangle" activation ``f_k = max(0, mean_j(z_j) - z_k)`` of its
distances ``z`` to the centroids, pooled (mean) over a region.

Here the patches are ``side x side`` pixels of the lightness block-averaged
by ``level`` photo pixels, one patch centred on every such pixel (the image
reflected at its border), and the pool is the coarse pixel (``scale / level``
level pixels a side): K features per coarse pixel.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from core.classify.texture import block_mean
from core.errors import TerrathemeError

#: added to each patch's variance (L units^2) before dividing by its root (flat patches stay finite)
CONTRAST_FLOOR = 2.0
#: added to the whitening eigenvalues (ZCA regulariser, normalised-patch units)
WHITEN_EPS = 0.1
#: patches encoded per block of work (bounds the memory to ~ rows x (D + K) floats)
ENCODE_ROWS = 65536


@dataclass(frozen=True)
class PatchWords:
    """A learned patch dictionary.

    Attributes
    ----------
    side : int
        Patch side in level pixels.
    level : int
        Photo pixels per level pixel along each axis (divides the feature scale).
    mean : (D,) float32 ndarray, D = side^2
        Mean normalised patch of the training patches.
    whiten : (D, D) float32 ndarray
        ZCA whitening matrix.
    centroids : (K, D) float32 ndarray
        k-means centroids in the whitened space.
    """

    side: int
    level: int
    mean: np.ndarray
    whiten: np.ndarray
    centroids: np.ndarray

    @property
    def count(self) -> int:
        """K, the number of features :func:`encode_words` gives."""
        return int(self.centroids.shape[0])


def level_image(lightness: np.ndarray, level: int) -> np.ndarray:
    """(H, W) float32 lightness block-averaged by ``level`` -> (ceil(H/level), ceil(W/level))."""
    lum = np.ascontiguousarray(lightness, dtype=np.float32)
    if lum.ndim == 3 and lum.shape[2] > 4:
        raise TerrathemeError("at most 4 channels")
    return lum if level == 1 else block_mean(lum, level)


def _patches(image: np.ndarray, side: int) -> np.ndarray:
    """Every ``side x side`` patch centred on a pixel (reflected border) -> (h * w, C, side^2)."""
    if image.ndim == 2:
        image = image[:, :, None]
    lo = (side - 1) // 2
    padded = np.pad(image, ((lo, side - 1 - lo), (lo, side - 1 - lo), (0, 0)), mode="reflect")
    view = sliding_window_view(padded, (side, side), axis=(0, 1))
    return view.reshape(-1, image.shape[2], side * side)


def normalise_patches(patches: np.ndarray) -> np.ndarray:
    """Each channel minus its mean, all over ``sqrt(var + CONTRAST_FLOOR)``: (n, C, s) ->
    (n, C * s) float32."""
    x = patches.astype(np.float32)
    x = (x - x.mean(2, keepdims=True)).reshape(len(x), -1)
    if NORMALISE["contrast"]:
        x = x / np.sqrt((x * x).mean(1, keepdims=True) + np.float32(CONTRAST_FLOOR))
    return x


NORMALISE = {"contrast": True}


def learn_words(lightness: Sequence[np.ndarray], count: int, side: int, level: int,
                seed: int = 0, per_image: int = 20000) -> PatchWords:
    """Learn a dictionary from the training photos' lightness.

    Parameters
    ----------
    lightness : sequence of (H, W) float32 ndarray
        Full-resolution lightness (L*) of each training photo.
    count : int
        K, dictionary size.
    side, level : int
        Patch side (level pixels) and level (photo pixels per level pixel).
    seed : int
    per_image : int
        Patches drawn (at random, seeded) from each photo.

    Returns
    -------
    PatchWords
    """
    from sklearn.cluster import MiniBatchKMeans

    if count < 2 or side < 2 or level < 1:
        raise TerrathemeError(f"patch words need count >= 2, side >= 2, level >= 1, not "
                              f"{count}, {side}, {level}")
    rng = np.random.default_rng(seed)
    drawn = []
    for lum in lightness:
        p = _patches(level_image(lum, level), side)
        drawn.append(p[rng.choice(len(p), min(per_image, len(p)), replace=False)])
    x = normalise_patches(np.concatenate(drawn))
    mean = x.mean(0)
    vals, vecs = np.linalg.eigh(np.cov(x - mean, rowvar=False))
    whiten = (vecs / np.sqrt(np.maximum(vals, 0.0) + WHITEN_EPS)) @ vecs.T
    z = (x - mean) @ whiten
    km = MiniBatchKMeans(count, random_state=seed, n_init=3, batch_size=4096).fit(z)
    return PatchWords(side, level, mean.astype(np.float32), whiten.astype(np.float32),
                      km.cluster_centers_.astype(np.float32))


def encode_words(lightness: np.ndarray, words: PatchWords, scale: int) -> np.ndarray:
    """Triangle activations of every patch, mean-pooled over each coarse pixel.

    Parameters
    ----------
    lightness : (H, W) float32 ndarray
        Full-resolution lightness.
    words : PatchWords
    scale : int
        Photo pixels per coarse pixel (a multiple of ``words.level``).

    Returns
    -------
    features : (ceil(H/scale), ceil(W/scale), K) float32 ndarray
    """
    if scale % words.level:
        raise TerrathemeError(f"patch level {words.level} does not divide scale {scale}")
    image = level_image(lightness, words.level)
    h, w = image.shape[:2]
    patches = _patches(image, words.side)
    c = words.centroids
    c_sq = (c * c).sum(1)[None, :]
    out = np.empty((h * w, words.count), np.float32)
    for s in range(0, len(patches), ENCODE_ROWS):
        z = (normalise_patches(patches[s : s + ENCODE_ROWS]) - words.mean) @ words.whiten
        d = np.sqrt(np.maximum((z * z).sum(1, keepdims=True) - 2.0 * (z @ c.T) + c_sq, 0.0))
        out[s : s + len(z)] = np.maximum(d.mean(1, keepdims=True) - d, 0.0)
    out = out.reshape(h, w, words.count)
    step = scale // words.level
    if step == 1:
        return out
    return block_mean(out, step)
