"""Metrics and simulated scribbles for ``bench_classify.py`` (not a test module)."""

from __future__ import annotations

import cv2
import numpy as np


def confusion(truth, pred, classes):
    """(C, C) counts, rows = truth, over pixels whose truth is one of ``classes``."""
    idx = {k: i for i, k in enumerate(classes)}
    lut_t = np.full(256, -1, np.int64)
    lut_p = np.full(256, -1, np.int64)
    for k, i in idx.items():
        lut_t[k] = i
        lut_p[k] = i
    t, p = lut_t[truth.ravel()], lut_p[pred.ravel()]
    keep = (t >= 0) & (p >= 0)
    c = len(classes)
    return np.bincount(t[keep] * c + p[keep], minlength=c * c).reshape(c, c)


def scores(cm, classes):
    tp = np.diag(cm).astype(float)
    union = cm.sum(0) + cm.sum(1) - tp
    iou = np.where(union > 0, tp / np.maximum(union, 1), np.nan)
    return {"oa": float(tp.sum() / max(cm.sum(), 1)),
            "miou": float(np.nanmean(iou)),
            "iou": {str(k): (None if np.isnan(v) else round(float(v), 4))
                    for k, v in zip(classes, iou, strict=True)}}


def simulate_scribbles(mask, classes, rng, budget=0.008, length=30, width=3):
    """Short straight strokes inside eroded class regions, <= ``budget`` of the pixels."""
    present = [k for k in classes if (mask == k).sum() > 0.002 * mask.size]
    out = np.zeros_like(mask)
    per_class = int(budget * mask.size / max(len(present), 1))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9))
    for k in present:
        region = cv2.erode((mask == k).astype(np.uint8), kernel).astype(bool)
        ys, xs = np.nonzero(region)
        if len(ys) == 0:
            continue
        painted = 0
        for _ in range(400):
            if painted >= per_class:
                break
            i = rng.integers(len(ys))
            a = rng.uniform(0, np.pi)
            dx, dy = np.cos(a) * length / 2, np.sin(a) * length / 2
            canvas = np.zeros(mask.shape, np.uint8)
            cv2.line(canvas, (int(xs[i] - dx), int(ys[i] - dy)),
                     (int(xs[i] + dx), int(ys[i] + dy)), 1, width)
            stroke = canvas.astype(bool) & region & (out == 0)
            stroke_px = int(stroke.sum())
            if painted + stroke_px > per_class:
                continue
            out[stroke] = k
            painted += stroke_px
    return out
