"""A tileable theme quilted from many small blocks of a class (image quilting on a torus).

For a class whose every window repeats visibly when tiled (a town patch's one junction).
Efros & Freeman, "Image Quilting for Texture Synthesis and Transfer", SIGGRAPH 2001,
§2: each next block is drawn among candidates within ``tolerance`` of the best overlap
error and meets the laid ones along minimum-error cuts. The grid wraps, so the result
tiles; the class's layout is lost on purpose, its grain and colours stay.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.seam_cut import min_error_cut


@dataclass(frozen=True)
class QuiltOptions:
    """How a theme is quilted.

    ``size``: side of the result (whole block steps); ``block``, ``overlap``: texels, overlap
    under half a block; ``candidates`` blocks to choose from, too small a class below
    ``min_candidates``; ``tolerance``: share of the best overlap error a candidate may
    exceed it by; ``feather``: Gaussian sigma (texels) softening each cut; ``seed``: draws
    among equally good blocks.
    """

    size: int = 256
    block: int = 48
    overlap: int = 12
    candidates: int = 150
    min_candidates: int = 16
    tolerance: float = 0.1
    feather: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        if not 2 <= 2 * self.overlap < self.block:
            raise TerrathemeError(
                f"quilt overlap must be 1 .. under half the block, got {self.overlap} of "
                f"{self.block}")
        if self.size < 2 * (self.block - self.overlap):
            raise TerrathemeError(f"quilt size {self.size} is under two block steps")

    def steps(self) -> int:
        """Blocks per side of the result."""
        return max(2, int(round(self.size / (self.block - self.overlap))))


def candidate_blocks(photo: np.ndarray, corners: np.ndarray,
                     options: QuiltOptions = QuiltOptions()) -> np.ndarray | None:
    """(n, block, block, 3) float32 blocks at ``(x, y)`` ``corners`` (n, 2), at their common mean.

    None with fewer than ``options.min_candidates`` corners or fewer than the quilt lays.
    """
    b = options.block
    corners = np.asarray(corners, np.int64).reshape(-1, 2)
    if len(corners) < max(options.min_candidates, options.steps() ** 2):
        return None
    h, w = photo.shape[:2]
    if (corners < 0).any() or (corners[:, 0] > w - b).any() or (corners[:, 1] > h - b).any():
        raise TerrathemeError(f"quilt blocks of {b} texels must lie inside the {w} x {h} photo")
    blocks = np.stack([photo[y : y + b, x : x + b, :3] for x, y in corners]).astype(np.float32)
    # Every block at the class's mean colour: the choice then follows the grain, not the
    # photo's lighting and shading (the colour map carries those).
    return blocks - blocks.mean(axis=(1, 2), keepdims=True) + blocks.mean(axis=(0, 1, 2))


def _old_side(err: np.ndarray, have: np.ndarray, overlap: int) -> np.ndarray:
    """(b, b) bool: texels of the block's overlap strips that keep what is laid already.

    Each fully laid strip splits along its minimum-error cut.
    """
    b = err.shape[0]
    o = overlap
    old = np.zeros((b, b), bool)
    cols = np.arange(o)
    # Left and right strips: top-to-bottom cuts (Efros & Freeman 2001, §2.1).
    if have[:, :o].all():
        path = min_error_cut(err[:, :o])
        old[:, :o] |= cols[None, :] < path[:, None]
    if have[:, b - o :].all():
        path = min_error_cut(err[:, b - o :])
        old[:, b - o :] |= cols[None, :] > path[:, None]
    # Top and bottom strips: the same cut on the transposed strip.
    if have[:o, :].all():
        path = min_error_cut(err[:o, :].T)
        old[:o, :] |= cols[:, None] < path[None, :]
    if have[b - o :, :].all():
        path = min_error_cut(err[b - o :, :].T)
        old[b - o :, :] |= cols[:, None] > path[None, :]
    return old


def quilt_tileable(photo: np.ndarray, corners: np.ndarray,
                   options: QuiltOptions = QuiltOptions()) -> np.ndarray | None:
    """(s, s, 3) uint8 tileable texture quilted from blocks of one class, or None (too few).

    ``corners``: (n, 2) ``(x, y)`` of candidate blocks in the (H, W, 3) uint8 photo;
    ``s`` is ``options.size`` rounded to whole steps ``block - overlap``.
    """
    blocks = candidate_blocks(photo, corners, options)
    if blocks is None:
        return None
    b, o = options.block, options.overlap
    step = b - o
    n = options.steps()
    side = n * step
    rng = np.random.default_rng(options.seed)
    out = np.zeros((side, side, 3), np.float32)
    laid = np.zeros((side, side), bool)
    flat = blocks.reshape(len(blocks), -1)
    used = np.zeros(len(blocks), bool)
    for r in range(n):
        for c in range(n):
            # The block's texels on the torus.
            at = np.ix_((r * step + np.arange(b)) % side, (c * step + np.arange(b)) % side)
            cur, have = out[at], laid[at]
            # Overlap error of every candidate against what is laid (§2.1), best within tolerance.
            laid_at = np.flatnonzero(np.repeat(have.ravel(), 3))
            cand, laid_cur = flat[:, laid_at], cur.ravel()[laid_at]
            diff = cand - laid_cur
            err = np.einsum("ij,ij->i", diff, diff)
            if laid_at.size:
                # Over the two sides' own spread: plain SSD would favour the calmest blocks
                # (for unrelated textures it is the sum of their variances).
                spread = cand - cand.mean(axis=1, keepdims=True)
                own = float(((laid_cur - laid_cur.mean()) ** 2).sum())
                err /= np.einsum("ij,ij->i", spread, spread) + own + 1.0
            # A block is laid once: a calm block would otherwise win every overlap and repeat.
            err[used] = np.inf
            ok = np.flatnonzero(err <= err.min() * (1.0 + options.tolerance) + 1e-9)
            pick = int(rng.choice(ok))
            used[pick] = True
            block = blocks[pick]
            # Minimum-error cuts through the laid strips; the rest takes the new block.
            texel_err = ((block - cur) ** 2).sum(axis=2)
            take = ~_old_side(texel_err, have, o)
            alpha = take.astype(np.float32)
            if options.feather > 0:
                alpha = cv2.GaussianBlur(alpha, (0, 0), options.feather)
            alpha = np.where(have, alpha, 1.0)[:, :, None]
            out[at] = alpha * block + (1.0 - alpha) * cur
            laid[at] = True
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
