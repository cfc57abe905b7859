"""The way back: weight maps, splatmaps or control maps from an engine to a vertex grid.

A map spans the grid corner to corner (:mod:`.layout`), so with ``step`` map pixels per
cell the vertices are the pixels at multiples of ``step``; each takes its strongest
theme (ties: the lower). Maps are read band by band: memory is one band of each map.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange.terrain3d import control_labels
from terratheme.core.io.images import ImageInfo, image_info, read_bands

#: map rows read at a time: memory holds one band of every map, not the maps
BAND_ROWS = 64
#: what ``new --from`` reads: Unity splatmaps, one weight map per theme, a Terrain3D control map
MAP_KINDS = ("splatmap", "weights", "terrain3d")
_NOUNS = {"splatmap": "splatmap", "weights": "weight map", "terrain3d": "control map"}


def labels_from_weights(weights: np.ndarray, n_themes: int) -> np.ndarray:
    """The strongest theme of every pixel (ties: lower theme) of ``(C, H, W)`` weights.

    Planes ``n_themes..C-1`` (a splatmap's unused channels) must be empty.
    """
    planes = np.asarray(weights)
    if planes.ndim != 3 or planes.shape[0] < n_themes:
        raise TerrathemeError(f"the maps hold {planes.shape[0] if planes.ndim == 3 else 0} "
                              f"weights per pixel, fewer than the {n_themes} themes named")
    extra = planes[n_themes:]
    if extra.size and extra.any():
        c = n_themes + int(np.argmax(extra.reshape(extra.shape[0], -1).any(axis=1)))
        raise TerrathemeError(f"weight channel {c} carries weight but only {n_themes} themes "
                              "were named: name one theme per channel")
    return np.argmax(planes[:n_themes], axis=0).astype(np.uint8)


def _check_map(path: str, info: ImageInfo, kind: str, first: ImageInfo) -> None:
    if kind == "splatmap" and (info.dtype != np.uint8 or info.channels not in (3, 4)):
        raise TerrathemeError(f"{path}: a splatmap is an 8-bit RGBA image, got "
                              f"{info.channels} channels of {info.dtype}")
    if kind == "weights" and (info.dtype not in (np.uint8, np.uint16) or info.channels == 2):
        raise TerrathemeError(f"{path}: a weight map is an 8 or 16-bit grey image, got "
                              f"{info.channels} channels of {info.dtype}")
    if kind == "terrain3d" and info.dtype != np.float32:
        raise TerrathemeError(
            f"{path}: a Terrain3D control map holds 32-bit floats (FORMAT_RF) whose bits are the "
            f"control values; this file holds {info.dtype} (export it from Terrain3D as EXR)")
    if (info.width, info.height) != (first.width, first.height) or (
            kind == "weights" and info.dtype != first.dtype):
        raise TerrathemeError(f"{path}: {info.width} x {info.height} {info.dtype} differs from "
                              f"the first {_NOUNS[kind]}'s {first.width} x {first.height} "
                              f"{first.dtype}")


def check_maps(paths: Sequence[str], kind: str) -> tuple[int, int]:
    """``(W, H)`` of engine maps of ``kind`` (:data:`MAP_KINDS`), checked on their headers
    alone (pixel type, channels, one size for all)."""
    if kind not in MAP_KINDS:
        raise TerrathemeError(f"unknown map kind {kind!r}: one of {', '.join(MAP_KINDS)}")
    if not paths:
        raise TerrathemeError(f"no {_NOUNS[kind]} given")
    infos = [image_info(p) for p in paths]
    for path, info in zip(paths, infos, strict=True):
        _check_map(str(path), info, kind, infos[0])
    return infos[0].width, infos[0].height


def _band_labels(kind: str, bands: list[np.ndarray], paths: Sequence[str],
                 n_themes: int) -> np.ndarray:
    """The strongest theme at every pixel of one band of each map, ``(h, w)`` uint8."""
    if kind == "terrain3d":
        return control_labels(np.ascontiguousarray(bands[0][:, :, 0]).view(np.uint32))
    if kind == "splatmap":
        planes = [np.moveaxis(b, 2, 0) for b in bands]
        planes = [np.concatenate([p, np.zeros((4 - len(p),) + p.shape[1:], p.dtype)])
                  for p in planes]
        return labels_from_weights(np.concatenate(planes), n_themes)
    for path, band in zip(paths, bands, strict=True):
        if band.shape[2] >= 3 and not (np.array_equal(band[:, :, 0], band[:, :, 1])
                                       and np.array_equal(band[:, :, 0], band[:, :, 2])):
            raise TerrathemeError(f"{path}: a weight map is a grey image, this one has "
                                  f"{band.shape[2]} channels of different values")
    return labels_from_weights(np.stack([b[:, :, 0] for b in bands]), n_themes)


def grid_from_maps(paths: Sequence[str], kind: str, n_themes: int, step: int) -> np.ndarray:
    """Vertex themes ``((H - 1) / step + 1, (W - 1) / step + 1)`` uint8 from engine maps.

    ``paths``: splatmaps (4 themes each), one weight map per theme, or one Terrain3D
    control map; weights beyond ``n_themes`` must be 0.
    """
    w, h = check_maps(paths, kind)
    _check_step(paths[0], w, h, step)
    out = np.empty(((h - 1) // step + 1, (w - 1) // step + 1), np.uint8)
    rows = max(step, BAND_ROWS // step * step)
    for parts in zip(*(read_bands(p, rows) for p in paths), strict=True):
        y = parts[0][0]
        # Bands start on vertex rows (rows is a multiple of step): keep every step-th row.
        bands = [band[::step, ::step] for _, band in parts]
        out[y // step:y // step + bands[0].shape[0]] = _band_labels(kind, bands, paths,
                                                                   n_themes)
    return out


def _check_step(path: str, w: int, h: int, step: int) -> None:
    if step < 1:
        raise TerrathemeError(f"step must be at least 1 map pixel per cell, got {step}")
    if (w - 1) % step or (h - 1) % step:
        raise TerrathemeError(
            f"{path}: a {w} x {h} map does not hold whole cells of {step} pixels: width - 1 "
            f"and height - 1 must be multiples of the step (maps span the grid corner to corner)")
    if w < step + 1 or h < step + 1:
        raise TerrathemeError(f"{path}: a {w} x {h} map holds no cell of {step} pixels")
