"""Metrics and simulated scribbles for ``bench_classify.py`` (not a test module)."""

from __future__ import annotations

from collections.abc import Sequence

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


def simulate_corrections(mask, classes, rng, target, budget_px, existing=None,
                         length=30, width=3, min_area=50, tries=4, smooth=9):
    """Correction strokes as a user adds them after seeing a result (round 2 of "corrections").

    The user looks at the regions ``target`` marks (the misclassified pixels, or the
    low-confidence ones the app highlights), takes its connected regions largest
    first and paints one short stroke of the TRUE class centred in each, then goes
    round again while paint is left. Strokes have the length and width of
    :func:`simulate_scribbles` and lie inside the eroded true-class region under
    their centre (the same 9 x 9 erosion), never on ``existing`` strokes.

    Parameters
    ----------
    mask : (H, W) uint8 ndarray
        True classes.
    classes : sequence of int
        Classes a user may paint (others, e.g. ignored classes, are never painted).
    rng : numpy Generator
    target : (H, W) bool ndarray
        Where the user wants to correct.
    budget_px : int
        Most pixels the new strokes may cover.
    existing : (H, W) uint8 ndarray, optional
        Strokes already painted (0 = none).
    min_area : int
        Target regions smaller than this many pixels are not worth a stroke.
    tries : int
        Stroke directions tried per stroke; the one covering most target pixels is
        kept (the user draws along the wrong region).
    smooth : int
        The user sees regions, not single pixels: regions are the connected
        components of the ``smooth`` x ``smooth`` majority of ``target`` (1 = as is);
        stroke centres are still ``target`` pixels.

    Returns
    -------
    strokes : (H, W) uint8 ndarray
        The new strokes only (0 = none, k = class k).
    """
    h, w = mask.shape
    out = np.zeros_like(mask)
    taken = np.zeros(mask.shape, bool) if existing is None else existing > 0
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9))
    # Eroded true-class regions: where a stroke of class k may lie.
    core = {k: cv2.erode((mask == k).astype(np.uint8), kernel).astype(bool) for k in classes}
    any_core = np.zeros(mask.shape, bool)
    for region in core.values():
        any_core |= region
    # Target regions as the user sees them (majority filter), largest first, each with
    # the target pixels a stroke may be centred on.
    seen = target.astype(np.uint8)
    if smooth > 1:
        seen = (cv2.blur(seen.astype(np.float32), (smooth, smooth)) > 0.5).astype(np.uint8)
    n, comp, stats, _ = cv2.connectedComponentsWithStats(seen, connectivity=8)
    centre_comp = np.where(any_core & target, comp, 0).ravel()
    order = np.argsort(centre_comp, kind="stable")
    bounds = np.searchsorted(centre_comp[order], np.arange(n + 1))
    regions = [order[bounds[c]:bounds[c + 1]]
               for c in sorted(range(1, n), key=lambda c: -stats[c, cv2.CC_STAT_AREA])
               if stats[c, cv2.CC_STAT_AREA] >= min_area and bounds[c + 1] > bounds[c]]
    half = length // 2 + width
    painted, misses = 0, 0
    # Rounds over the regions until the paint is spent or no stroke fits any more.
    while regions and painted < budget_px and misses < 3 * len(regions):
        for cand in regions:
            if painted >= budget_px or misses >= 3 * len(regions):
                break
            y, x = divmod(int(cand[rng.integers(len(cand))]), w)
            k = int(mask[y, x])
            y0, y1, x0, x1 = max(y - half, 0), min(y + half + 1, h), max(x - half, 0), \
                min(x + half + 1, w)
            allowed = core[k][y0:y1, x0:x1] & ~taken[y0:y1, x0:x1] & (out[y0:y1, x0:x1] == 0)
            best, best_hits = None, -1
            # A few directions through the centre; keep the one along the target region.
            for _ in range(tries):
                a = rng.uniform(0, np.pi)
                dx, dy = np.cos(a) * length / 2, np.sin(a) * length / 2
                canvas = np.zeros(allowed.shape, np.uint8)
                cx, cy = x - x0, y - y0
                cv2.line(canvas, (int(cx - dx), int(cy - dy)), (int(cx + dx), int(cy + dy)),
                         1, width)
                stroke = canvas.astype(bool) & allowed
                hits = int((stroke & target[y0:y1, x0:x1]).sum())
                if hits > best_hits:
                    best, best_hits = stroke, hits
            stroke_px = int(best.sum())
            if stroke_px == 0 or painted + stroke_px > budget_px:
                misses += 1
                continue
            out[y0:y1, x0:x1][best] = k
            painted += stroke_px
    return out


def draw_seeds(first, n):
    """Seeds of ``n`` independent stroke draws: ``first``, then ``[first, 1]``, ``[first, 2]``..."""
    return [first] + [[first, d] for d in range(1, n)]


def draw_rows(reps, sets):
    """Result row of one method from per-draw ``{photo: confusion}`` (draws = repeats).

    ``sets`` are the photos as :func:`bench_classify.scribble_sets` gives them.
    """
    classes = {n: c for _f, n, c, _x in sets}
    mious = [{n: scores(cm, classes[n])["miou"] for n, cm in per.items()} for per in reps]
    dubai = [n for n in reps[0] if n.startswith("image_part")]
    pooled = [scores(sum(per[n] for n in dubai), [1, 2, 3, 4, 5]) for per in reps]
    return {
        "mean_miou_over_photos": float(np.mean([np.mean(list(m.values())) for m in mious])),
        "mean_miou_per_repeat": [round(float(np.mean(list(m.values()))), 4) for m in mious],
        "dubai_mean_miou_over_photos": float(np.mean([[m[n] for n in dubai] for m in mious])),
        "miou_per_photo": {n: round(float(np.mean([m[n] for m in mious])), 4)
                           for n in reps[0]},
        "dubai_pooled": scores(sum(per[n] for per in reps for n in dubai), [1, 2, 3, 4, 5]),
        "dubai_pooled_miou_per_repeat": [round(p["miou"], 4) for p in pooled],
    }


def majority_classes(labels: np.ndarray, truth: np.ndarray,
                     classes: Sequence[int]) -> dict[int, int]:
    """``{label: class}``: for every label, the ground-truth class among ``classes`` it covers most.

    Truth values outside ``classes`` are ignored; labels covering no scored pixel
    are left out.
    """
    lab = np.asarray(labels).ravel().astype(np.int64)
    tru = np.asarray(truth).ravel().astype(np.int64)
    lut = np.full(max(int(tru.max(initial=0)), max(classes, default=0)) + 1, -1, np.int64)
    for i, k in enumerate(classes):
        lut[k] = i
    ti = lut[np.clip(tru, 0, lut.size - 1)]
    keep = ti >= 0
    nl = int(lab.max(initial=0)) + 1
    counts = np.bincount(lab[keep] * len(classes) + ti[keep],
                         minlength=nl * len(classes)).reshape(nl, len(classes))
    return {int(t): int(classes[int(np.argmax(row))]) for t, row in enumerate(counts) if row.any()}


def class_iou_scores(labels: np.ndarray, truth: np.ndarray, classes: Sequence[int]) -> dict:
    """Per-class IoU of a label view against ground truth, each label mapped to its majority class.

    Returns ``{"miou": float, "iou": {class: float or None}, "mapping": {label:
    class}}``; truth values outside ``classes`` are ignored, and a class absent from
    both truth and mapped labels has IoU None and does not count in the mean.
    """
    labels, truth = np.asarray(labels), np.asarray(truth)
    if labels.shape != truth.shape or labels.ndim != 2:
        raise ValueError(f"label view {labels.shape} and truth {truth.shape} differ")
    if not classes:
        raise ValueError("no classes to score")
    mapping = majority_classes(labels, truth, classes)
    lut = np.full(int(labels.max(initial=0)) + 1, -1, np.int64)
    for t, k in mapping.items():
        lut[t] = k
    pred = lut[labels.astype(np.int64)]
    scored = np.isin(truth, classes)
    iou: dict[int, float | None] = {}
    for k in classes:
        t, p = (truth == k) & scored, (pred == k) & scored
        union = int((t | p).sum())
        iou[int(k)] = None if union == 0 else float((t & p).sum() / union)
    present = [v for v in iou.values() if v is not None]
    return {"miou": float(np.mean(present)) if present else float("nan"), "iou": iou,
            "mapping": mapping}
