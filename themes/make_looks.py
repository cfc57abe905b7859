"""Make ``themes/looks.json``: how the shipped themes' classes look in the Dubai photos.

Run: ``.venv/bin/python themes/make_looks.py [--dubai ../shared/data/dubai] [--evaluate]``

For every Dubai photo (Humans in the Loop, CC0 1.0) and every mask class
with at least ``MIN_PIXELS`` pixels, the class's appearance (mean Lab and
band-pass energy, :func:`core.themes.matching.class_appearances`) under the
shipped theme named for that class (:data:`THEME_OF_CLASS`); see
:mod:`core.themes.looks`. ``--evaluate`` scores the naming of unsupervised
classes leaving one tile out (a class is named right when its name is a
theme of its majority mask class, weighted by pixels), with the theme
textures alone and with the looks.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from terratheme.core.classify import classify_unsupervised  # noqa: E402
from terratheme.core.io.atomic import write_bytes_atomic  # noqa: E402
from terratheme.core.io.images import read_image, read_labels  # noqa: E402
from terratheme.core.themes.library import read_theme_library  # noqa: E402
from terratheme.core.themes.looks import LOOKS_FILE  # noqa: E402
from terratheme.core.themes.matching import class_appearances, shipped_names  # noqa: E402
from terratheme.core.themes.patch_search import texture_stats  # noqa: E402

#: Dubai mask class -> the shipped theme its looks are listed under
THEME_OF_CLASS = {1: "town", 2: "sand", 3: "road", 4: "grass", 5: "water"}
#: names counted right for a class of that majority mask class (--evaluate)
RIGHT_NAMES = {1: {"town"}, 2: {"sand", "rock"}, 3: {"road", "rock"},
               4: {"grass", "forest", "crop field"}, 5: {"water"}}
#: a class smaller than this in a photo gives no look
MIN_PIXELS = 2000


def photo_looks(dubai: Path):
    """Per photo: (name, tile, {class: Appearance}, stats, rgb, mask)."""
    for path in sorted((dubai / "images").glob("*.jpg")):
        rgb = read_image(path)[:, :, :3]
        mask = read_labels(dubai / "masks" / (path.stem + ".png"))
        stats = texture_stats(rgb)
        looks = {c: class_appearances(stats, mask, [c])[0] for c in THEME_OF_CLASS
                 if int((mask == c).sum()) >= MIN_PIXELS}
        yield path.name, path.stem.rsplit("t", 1)[-1], looks, stats, rgb, mask


def evaluate(rows, library) -> dict:
    """Share of pixels whose unsupervised class is named right, leaving each tile out."""
    right = {"textures": 0, "textures+looks": 0}
    total = 0
    for name, tile, _looks, stats, rgb, mask in rows:
        others = [(THEME_OF_CLASS[c], a) for _n, t, lk, *_ in rows if t != tile
                  for c, a in lk.items()]
        result = classify_unsupervised(rgb)
        apps = class_appearances(stats, result.labels, result.classes)
        named = {"textures": shipped_names(apps, library),
                 "textures+looks": shipped_names(apps, library, others)}
        for i, c in enumerate(result.classes):
            gt = mask[result.labels == c]
            gt = gt[(gt >= 1) & (gt <= 5)]
            if gt.size == 0:
                continue
            majority = int(np.bincount(gt, minlength=6).argmax())
            for key, names in named.items():
                base = names[i].rsplit(" ", 1)[0] if names[i][-1].isdigit() else names[i]
                right[key] += gt.size * (base in RIGHT_NAMES[majority])
            total += gt.size
        print(f"  {name}: {named['textures']} -> {named['textures+looks']}", flush=True)
    return {key: value / max(total, 1) for key, value in right.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dubai", default=str(HERE.parents[1] / "shared" / "data" / "dubai"))
    ap.add_argument("--evaluate", action="store_true")
    args = ap.parse_args()
    dubai = Path(args.dubai)
    if not (dubai / "masks").is_dir():
        raise SystemExit(f"{dubai}: Dubai photos not found")
    rows = list(photo_looks(dubai))
    looks = [{"name": THEME_OF_CLASS[c], "lab": [round(float(v), 3) for v in a.lab],
              "energy": round(float(a.energy), 7), "photo": name}
             for name, _tile, lk, *_ in rows for c, a in sorted(lk.items())]
    doc = {"version": 1,
           "source": "Humans in the Loop, 'Semantic segmentation of aerial imagery' (Dubai, "
                     "MBRSC), CC0 1.0: mean Lab and band-pass energy of each mask class",
           "looks": looks}
    write_bytes_atomic(HERE / LOOKS_FILE, (json.dumps(doc, indent=0) + "\n").encode())
    print(f"{HERE / LOOKS_FILE}: {len(looks)} looks from {len(rows)} photos")
    if args.evaluate:
        print(evaluate(rows, read_theme_library(HERE)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
