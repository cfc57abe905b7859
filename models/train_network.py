"""Train the shipped ``aerial`` network (a light U-Net) on the CC0 Dubai photos, export ONNX.

Run (PyTorch from the ``train`` extra, in any venv)::

    python models/train_network.py [--data DIR] [--iterations N] [--holdout TILE]

DIR defaults to ``../shared/data/dubai`` beside the repository (Humans in the
Loop, "Semantic segmentation of aerial imagery", Dubai, MBRSC satellite, CC0
1.0; 54 photo/mask pairs of tiles 1-6). Classes 1-5 (building, land, road,
vegetation, water) are learnt; 6 (Unlabeled), 7 and 0 are ignored by the loss.
The photos of tile ``--holdout`` (0: none) are left out of training and scored
at each checkpoint, so the index's scores are those of an area never seen.

Writes ``models/aerial.onnx`` (input ``photo``: float32 RGB 0..255, N x 3 x H x
W, H and W multiples of :data:`MULTIPLE`; output ``probabilities``: N x 5 x H
x W, softmax; the normalisation is inside the graph, so inference cannot
disagree with training) and its entry in ``models/models.json``. The network
runs on the photo resized by :data:`SCALE`; training crops are drawn around
that scale with scale, rotation, flip, colour, exposure, blur, noise and JPEG
augmentation so that it carries to other areas and sensors.

``--channels`` sets the four levels' widths (default :data:`CHANNELS`); a checkpoint's widths
are read from its weights, and ``--continue`` / ``--resume`` with other widths stop with a
clear message.

The shipped model: ``--holdout 0 --iterations 4500 --every 500`` (seed 0; all six tiles),
about 30 minutes on a quiet 2-core machine; the recipe is validated with ``--holdout 1``,
whose tile-1 scores the index keeps. A run stopped at a checkpoint (``--checkpoints C``)
goes on exactly with ``--continue C/aerial_NNNNN.pt`` and the same options.

Reproducible: fixed seeds, deterministic algorithms, two threads
(``torch.set_num_threads(2)``); checkpoints and the ONNX file are written every
``--every`` iterations, so a run cut short still leaves a usable model.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import random
import sys
import time
import warnings
from pathlib import Path

import cv2
import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

HERE = Path(__file__).resolve().parent
NAME = "aerial"
FILE = "aerial.onnx"
CLASS_NAMES = {1: "building", 2: "land", 3: "road", 4: "vegetation", 5: "water"}
N_CLASSES = len(CLASS_NAMES)
IGNORE = 255
#: the photo is resized by this factor before the network sees it (speed; see models.json)
SCALE = 0.5
#: the network's input sides must be multiples of this (three 2x poolings)
MULTIPLE = 8
CHANNELS = (16, 32, 48, 64)
#: ImageNet-like RGB statistics of 0..255 photos, applied inside the graph
MEAN = (120.0, 115.0, 105.0)
STD = (60.0, 58.0, 58.0)
CROP = 160
BATCH = 8


def conv(cin: int, cout: int, k: int = 3) -> nn.Sequential:
    """3x3 (or k x k) convolution, batch norm, ReLU (folded into one conv by ONNX runtimes)."""
    return nn.Sequential(nn.Conv2d(cin, cout, k, padding=k // 2, bias=False),
                         nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class LightUNet(nn.Module):
    """Four-level U-Net, additive skips with 1x1 projections (light decoder)."""

    def __init__(self, channels: tuple[int, ...] = CHANNELS, n_classes: int = N_CLASSES):
        super().__init__()
        c1, c2, c3, c4 = channels
        self.channels = tuple(channels)
        self.register_buffer("mean", torch.tensor(MEAN).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(STD).view(1, 3, 1, 1))
        self.enc1 = nn.Sequential(conv(3, c1), conv(c1, c1))
        self.enc2 = nn.Sequential(conv(c1, c2), conv(c2, c2))
        self.enc3 = nn.Sequential(conv(c2, c3), conv(c3, c3))
        self.enc4 = nn.Sequential(conv(c3, c4), conv(c4, c4), conv(c4, c4))
        self.up3, self.dec3 = conv(c4, c3, 1), conv(c3, c3)
        self.up2, self.dec2 = conv(c3, c2, 1), conv(c2, c2)
        self.up1, self.dec1 = conv(c2, c1, 1), conv(c1, c1)
        self.head = nn.Conv2d(c1, n_classes, 1)

    def logits(self, x: torch.Tensor) -> torch.Tensor:
        x = (x - self.mean) / self.std
        e1 = self.enc1(x)
        e2 = self.enc2(F.max_pool2d(e1, 2))
        e3 = self.enc3(F.max_pool2d(e2, 2))
        e4 = self.enc4(F.max_pool2d(e3, 2))
        d3 = self.dec3(self.up3(F.interpolate(e4, scale_factor=2.0, mode="nearest")) + e3)
        d2 = self.dec2(self.up2(F.interpolate(d3, scale_factor=2.0, mode="nearest")) + e2)
        d1 = self.dec1(self.up1(F.interpolate(d2, scale_factor=2.0, mode="nearest")) + e1)
        return self.head(d1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.softmax(self.logits(x), dim=1)


def tile_of(path: Path) -> int:
    """Tile number of a Dubai photo name (``image_part_001t3.jpg`` -> 3)."""
    return int(path.stem.rsplit("t", 1)[1])


def load_pairs(folder: Path, tiles: set[int]) -> list[tuple[np.ndarray, np.ndarray]]:
    """(RGB uint8, label uint8 with 0..4 = classes 1..5 and IGNORE) of the given tiles."""
    pairs = []
    for path in sorted((folder / "images").glob("*.jpg")):
        if tile_of(path) not in tiles:
            continue
        photo = cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        mask = cv2.imread(str(folder / "masks" / (path.stem + ".png")), cv2.IMREAD_UNCHANGED)
        if mask.ndim == 3:
            mask = mask[:, :, 0]
        label = np.full(mask.shape, IGNORE, np.uint8)
        for value in CLASS_NAMES:
            label[mask == value] = value - 1
        pairs.append((photo, label))
    if not pairs:
        raise SystemExit(f"{folder}: no Dubai photos of tiles {sorted(tiles)}")
    return pairs


def augment_colour(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Colour, exposure, blur, noise and JPEG re-coding of one RGB uint8 crop."""
    x = img.astype(np.float32) / 255.0
    x = x ** rng.uniform(0.7, 1.4)                                 # exposure curve
    x = x * rng.uniform(0.75, 1.25) + rng.uniform(-0.1, 0.1)       # gain, offset
    x = x * rng.uniform(0.75, 1.25, size=3)                        # white balance
    x = np.clip(x, 0.0, 1.0).astype(np.float32)
    hsv = cv2.cvtColor(x, cv2.COLOR_RGB2HSV)
    hsv[:, :, 0] = (hsv[:, :, 0] + rng.uniform(-15.0, 15.0)) % 360.0  # hue
    x = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
    grey = x.mean(axis=2, keepdims=True)
    x = grey + (x - grey) * (0.0 if rng.random() < 0.1 else rng.uniform(0.3, 1.6))  # saturation
    mean = x.mean()
    x = mean + (x - mean) * rng.uniform(0.7, 1.3)                  # contrast
    if rng.random() < 0.3:
        sigma = rng.uniform(0.3, 1.5)
        x = cv2.GaussianBlur(x, (0, 0), sigma)
    if rng.random() < 0.3:
        x = x + rng.normal(0.0, rng.uniform(0.005, 0.04), x.shape).astype(np.float32)
    out = np.clip(x * 255.0 + 0.5, 0, 255).astype(np.uint8)
    if rng.random() < 0.4:
        ok, data = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(25, 95))])
        out = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    return out


def random_crop(pair: tuple[np.ndarray, np.ndarray], rng: np.random.Generator,
                size: int = CROP) -> tuple[np.ndarray, np.ndarray]:
    """A ``size`` crop at a random scale around :data:`SCALE`, angle and flip."""
    photo, label = pair
    scale = SCALE * math.exp(rng.uniform(math.log(0.6), math.log(1.6)))
    angle = rng.uniform(0.0, 360.0) if rng.random() < 0.5 else 90.0 * rng.integers(4)
    h, w = label.shape
    cy, cx = rng.uniform(0, h), rng.uniform(0, w)
    m = cv2.getRotationMatrix2D((cx, cy), angle, scale)
    m[:, 2] += (size / 2.0 - cx, size / 2.0 - cy)
    img = cv2.warpAffine(photo, m, (size, size), flags=cv2.INTER_AREA if scale < 1 else
                         cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101)
    lab = cv2.warpAffine(label, m, (size, size), flags=cv2.INTER_NEAREST,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=IGNORE)
    if rng.random() < 0.5:
        img, lab = img[:, ::-1], lab[:, ::-1]
    return augment_colour(np.ascontiguousarray(img), rng), np.ascontiguousarray(lab)


def batch(pairs: list, weights: np.ndarray, rng: np.random.Generator
          ) -> tuple[torch.Tensor, torch.Tensor]:
    """One training batch; photos drawn in proportion to their pixel counts."""
    xs, ys = [], []
    for _ in range(BATCH):
        img, lab = random_crop(pairs[rng.choice(len(pairs), p=weights)], rng)
        xs.append(img.transpose(2, 0, 1))
        ys.append(lab)
    return (torch.from_numpy(np.stack(xs).astype(np.float32)),
            torch.from_numpy(np.stack(ys).astype(np.int64)))


def predict(net: LightUNet, photo: np.ndarray) -> np.ndarray:
    """Class index (0..4) per pixel of a whole photo, at :data:`SCALE` then upsampled."""
    h, w = photo.shape[:2]
    sh, sw = (max(MULTIPLE, int(round(s * SCALE / MULTIPLE)) * MULTIPLE) for s in (h, w))
    small = cv2.resize(photo, (sw, sh), interpolation=cv2.INTER_AREA)
    with torch.no_grad():
        x = torch.from_numpy(small.transpose(2, 0, 1)[None].astype(np.float32))
        p = net(x)[0].numpy().transpose(1, 2, 0)
    p = cv2.resize(p, (w, h), interpolation=cv2.INTER_LINEAR)
    return p.argmax(axis=2)


def score(net: LightUNet, pairs: list) -> dict:
    """mIoU, per-class IoU and overall accuracy of the network on ``pairs``."""
    net.eval()
    conf = np.zeros((N_CLASSES, N_CLASSES), np.int64)
    for photo, label in pairs:
        pred = predict(net, photo)
        keep = label != IGNORE
        conf += np.bincount(label[keep].astype(np.int64) * N_CLASSES + pred[keep],
                            minlength=N_CLASSES ** 2).reshape(N_CLASSES, N_CLASSES)
    net.train()
    inter = np.diag(conf).astype(float)
    union = conf.sum(0) + conf.sum(1) - inter
    iou = np.where(union > 0, inter / np.maximum(union, 1), np.nan)
    return {"miou": round(float(np.nanmean(iou)), 4),
            "iou": {CLASS_NAMES[i + 1]: round(float(v), 4) for i, v in enumerate(iou)},
            "overall_accuracy": round(float(inter.sum() / max(conf.sum(), 1)), 4)}


def export(net: LightUNet, path: Path) -> None:
    """ONNX of the network (dynamic H, W), written atomically."""
    net.eval()
    tmp = path.with_suffix(".tmp.onnx")
    torch.onnx.export(net, torch.zeros(1, 3, 64, 64), str(tmp), input_names=["photo"],
                      output_names=["probabilities"], opset_version=13, dynamo=False,
                      dynamic_axes={"photo": {0: "n", 2: "h", 3: "w"},
                                    "probabilities": {0: "n", 2: "h", 3: "w"}})
    os.replace(tmp, path)
    net.train()


def write_index(out: Path, scores: dict | None, holdout: int, done: int, total: int,
                channels: tuple[int, ...] = CHANNELS) -> None:
    """The model's entry in ``models.json`` (other entries kept; widths named unless default)."""
    index_path = out / "models.json"
    index = json.loads(index_path.read_text()) if index_path.is_file() else {"models": {}}
    data = (out / FILE).read_bytes()
    tiles = sorted(set(range(1, 7)) - {holdout})
    held = (f"scores on held-out tile {holdout} (never seen in training)" if holdout
            else "trained on every tile (no held-out scores)")
    net = "light U-Net" if tuple(channels) == CHANNELS else \
        f"light U-Net, channels {'/'.join(map(str, channels))}"
    index["models"][NAME] = {
        "file": FILE,
        "classes": {str(k): v for k, v in CLASS_NAMES.items()},
        "description": ("aerial / satellite orthophotos: building, land, road, vegetation, "
                        f"water ({net}, run at {SCALE}x the photo's size; trained on "
                        f"Dubai tiles {tiles}, checkpoint {done} of "
                        f"{total} iterations; {held})"),
        "trained_on": ("Humans in the Loop, 'Semantic segmentation of aerial imagery' "
                       "(Dubai, MBRSC), CC0 1.0"),
        "tiles": tiles,
        "scale": SCALE,
        "multiple": MULTIPLE,
        "scores": scores or {},
        "bytes": len(data),
        "sha256": hashlib.sha256(data).hexdigest(),
    }
    tmp = index_path.with_suffix(".tmp")
    tmp.write_text(json.dumps(index, indent=1) + "\n")
    os.replace(tmp, index_path)


def class_weights(pairs: list) -> torch.Tensor:
    """Inverse square-root class frequencies, mean 1 (roads and buildings count more)."""
    counts = sum(np.bincount(lab[lab != IGNORE], minlength=N_CLASSES) for _, lab in pairs)
    w = 1.0 / np.sqrt(np.maximum(counts, 1) / counts.sum())
    return torch.tensor(w / w.mean(), dtype=torch.float32)


def checkpoint_channels(state: dict) -> tuple[int, ...]:
    """The four level widths of a :class:`LightUNet` state dict (first conv of each level)."""
    return tuple(int(state[f"enc{level}.0.0.weight"].shape[0]) for level in range(1, 5))


def load_checkpoint(path: Path, channels: tuple[int, ...], weights_only: bool) -> dict:
    """A checkpoint of a net with ``channels``; exits with one line if its widths differ."""
    saved = torch.load(path, weights_only=weights_only)
    found = checkpoint_channels(saved["net"])
    if found != tuple(channels):
        raise SystemExit(f"{path}: checkpoint has channels {' '.join(map(str, found))}, "
                         f"this run --channels {' '.join(map(str, channels))}")
    return saved


def resume_run(path: Path, net: LightUNet, opt: torch.optim.Optimizer,
               sched: torch.optim.lr_scheduler.LRScheduler, train: list, sizes: np.ndarray,
               rng: np.random.Generator) -> int:
    """Put a run back where its checkpoint ``path`` left it; returns the checkpoint's iteration.

    Weights and optimiser moments come from the checkpoint; the schedule is stepped to the
    same iteration and the crop generator is restored (or, for a checkpoint that lacks its
    state, replayed batch by batch), so the run goes on exactly as if never stopped.
    """
    saved = load_checkpoint(path, net.channels, weights_only=False)
    done = int(saved["it"])
    net.load_state_dict(saved["net"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # stepping the schedule without optimiser steps
        for _ in range(done):
            sched.step()
    opt.load_state_dict(saved["opt"])
    if "rng" in saved:
        rng.bit_generator.state = saved["rng"]
    else:
        for _ in range(done):
            batch(train, sizes / sizes.sum(), rng)
    return done


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=HERE.parent.parent / "shared/data/dubai")
    parser.add_argument("--out", type=Path, default=HERE)
    parser.add_argument("--iterations", type=int, default=480)
    parser.add_argument("--every", type=int, default=80)
    parser.add_argument("--holdout", type=int, default=1, help="tile left out (0: none)")
    parser.add_argument("--channels", type=int, nargs=4, default=list(CHANNELS),
                        metavar="C", help="widths of the four levels (default %(default)s)")
    parser.add_argument("--lr", type=float, default=4e-3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--resume", type=Path, default=None,
                        help="start from this checkpoint's weights (new schedule)")
    parser.add_argument("--continue", dest="continue_from", type=Path, default=None,
                        help="go on with the run that wrote this checkpoint (same --iterations, "
                             "--lr, --seed): the result is that of the uninterrupted run")
    parser.add_argument("--until", type=int, default=None,
                        help="stop after this iteration of the schedule (default: its end)")
    parser.add_argument("--checkpoints", type=Path, default=None,
                        help="folder for .pt checkpoints (default: none kept)")
    args = parser.parse_args(argv)
    if min(args.channels) < 1:
        parser.error("--channels must be positive")

    torch.set_num_threads(2)
    cv2.setNumThreads(1)
    torch.manual_seed(args.seed)
    random.seed(args.seed)
    rng = np.random.default_rng(args.seed)
    torch.use_deterministic_algorithms(True)

    train = load_pairs(args.data, set(range(1, 7)) - {args.holdout})
    held = load_pairs(args.data, {args.holdout}) if args.holdout else []
    sizes = np.array([lab.size for _, lab in train], float)
    net = LightUNet(tuple(args.channels))
    if args.resume:
        net.load_state_dict(load_checkpoint(args.resume, net.channels, weights_only=True)["net"])
    opt = torch.optim.AdamW(net.parameters(), lr=args.lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=args.iterations,
                                                pct_start=0.1)
    weights = class_weights(train)
    print(f"{len(train)} training photos, {len(held)} held out; class weights "
          f"{weights.numpy().round(2).tolist()}", flush=True)
    first = 1
    if args.continue_from:
        first = resume_run(args.continue_from, net, opt, sched, train, sizes, rng) + 1
    start, running, scores = time.time(), 0.0, None
    last = min(args.iterations, args.until or args.iterations)
    for it in range(first, last + 1):
        x, y = batch(train, sizes / sizes.sum(), rng)
        loss = F.cross_entropy(net.logits(x), y, weight=weights, ignore_index=IGNORE)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        running = 0.98 * running + 0.02 * loss.item() if it > first else loss.item()
        if it % 25 == 0:
            print(f"it {it} loss {running:.4f} {time.time() - start:.0f}s", flush=True)
        if it % args.every == 0 or it == last:
            scores = score(net, held) if held else None
            export(net, args.out / FILE)
            write_index(args.out, scores, args.holdout, it, args.iterations, net.channels)
            if args.checkpoints:
                args.checkpoints.mkdir(parents=True, exist_ok=True)
                torch.save({"it": it, "net": net.state_dict(), "opt": opt.state_dict(),
                            "rng": rng.bit_generator.state},
                           args.checkpoints / f"aerial_{it:05d}.pt")
            print(f"checkpoint {it}: {json.dumps(scores)} {time.time() - start:.0f}s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
