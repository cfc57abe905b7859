"""Train the shipped ``aerial-forest`` classifier on every CC0 Dubai photo, and index it.

Run: ``.venv/bin/python models/train_aerial.py [--data DIR]`` (DIR defaults to
``../shared/data/dubai`` beside the repository: Humans in the Loop, "Semantic
segmentation of aerial imagery", Dubai, MBRSC satellite imagery, CC0 1.0; 54
photos of tiles 1-6 with full label masks). Writes ``models/aerial.model``
(:meth:`core.classify.Classifier.save`) and its entry in ``models/models.json``
(:mod:`core.classify.shipped`): the legend's classes 1-5 named building, land,
road, vegetation, water (6 "Unlabeled" and 7 ignored).

The library's supervised defaults (trained on 54 photos, so no test-time
adaptation: ``SupervisedOptions.adapt``), with ``N_TREES`` trees of depth
``MAX_DEPTH`` on at most ``SAMPLES_PER_CLASS`` coarse pixels per class, to keep
the file small (30 trees: 0.448 mean tile mIoU leaving each Dubai tile out in
the exploration runs, against 0.452 with 50 trees at 1.6x the bytes);
bench_classify.py part ``aerial`` scores it on LoveDA, Potsdam and DeepGlobe.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from terratheme.core.classify import SupervisedOptions, train_classifier  # noqa: E402
from terratheme.core.classify.shipped import MODELS_INDEX  # noqa: E402
from terratheme.core.io.atomic import write_bytes_atomic  # noqa: E402
from terratheme.core.io.images import read_image  # noqa: E402

NAME = "aerial-forest"
FILE = "aerial.model"
CLASS_NAMES = {1: "building", 2: "land", 3: "road", 4: "vegetation", 5: "water"}
IGNORE = (6, 7)
N_TREES = 30
MAX_DEPTH = 12
SAMPLES_PER_CLASS = 8000


def options() -> SupervisedOptions:
    """The shipped model's training options."""
    return SupervisedOptions(ignore_classes=IGNORE, n_trees=N_TREES, max_depth=MAX_DEPTH,
                             max_samples_per_class=SAMPLES_PER_CLASS)


def dubai_pairs(folder: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every (photo, mask) pair of the Dubai folder, in name order."""
    photos = sorted((folder / "images").glob("*.jpg"))
    if not photos:
        raise SystemExit(f"{folder}: no Dubai photos (images/*.jpg)")
    pairs = []
    for path in photos:
        mask = read_image(folder / "masks" / (path.stem + ".png"))[:, :, 0]
        pairs.append((np.ascontiguousarray(read_image(path)[:, :, :3]), mask))
    return pairs


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=HERE.parent.parent / "shared" / "data" /
                        "dubai")
    parser.add_argument("--out", type=Path, default=HERE)
    args = parser.parse_args()
    pairs = dubai_pairs(args.data)
    model = train_classifier(pairs, options())
    path = args.out / FILE
    model.save(path)
    data = path.read_bytes()
    index_path = args.out / MODELS_INDEX
    index = json.loads(index_path.read_text()) if index_path.is_file() else {"models": {}}
    index["models"][NAME] = {
        "file": FILE,
        "classes": {str(k): v for k, v in CLASS_NAMES.items()},
        "description": "aerial / satellite orthophotos of arid areas: building, land, road, "
                       "vegetation, water (Extra-Trees on Dubai photos)",
        "trained_on": f"{len(pairs)} photos of Humans in the Loop, 'Semantic segmentation "
                      "of aerial imagery' (Dubai, MBRSC), CC0 1.0",
        "bytes": len(data),
        "sha256": hashlib.sha256(data).hexdigest(),
    }
    write_bytes_atomic(index_path, (json.dumps(index, indent=1) + "\n").encode())
    print(f"{path}: {len(data):,} bytes, {len(pairs)} photos, classes {model.classes}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
