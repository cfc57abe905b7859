"""The shipped network (``--model aerial``) against the forest, on areas neither was shown.

Run: ``nice -n 10 .venv/bin/python benchmarks/bench_classify_network.py [--only ROWS]``
(needs ``../shared/data``). Writes ``benchmarks/results/classify_network.json`` and
``classify_network.png`` (accuracy against speed).

Rows:
  network          the shipped ``aerial`` network (models/train_network.py); tile 1 is
                   seen in training when its index entry's ``tiles`` list it;
  forest           the forest ``aerial-forest`` (models/train_aerial.py) as shipped: trained
                   on all 54 Dubai photos, tile 1 included, so its tile-1 figures are
                   optimistic;
  forest-holdout   the same forest recipe trained here on tiles 2-6 only: the fair peer
                   on tile 1.

Scored: Dubai tile 1 (classes 1-5, 6/7/0 not scored; IoU pooled over its 9 photos;
each row's ``tile_1_seen_in_training`` says whether it is a held-out score), and LoveDA,
Potsdam, DeepGlobe mapped to the classes they share with ours
(``classify_aerial.COMMON``, ``shared_scores``); speed as photo Mpx per second of
``predict``: wall clock on this shared 2-core machine (the load average is recorded), and
per CPU-second of the process (all its threads), which the other jobs do not change:
on 2 free cores a model runs at up to twice that.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "models"))

from classify_aerial import COMMON, shared_scores  # noqa: E402
from classify_eval import confusion, scores  # noqa: E402
from terratheme.core.classify import load_model, train_classifier  # noqa: E402
from terratheme.core.classify.shipped import MODELS_INDEX, SHIPPED_MODELS_DIR  # noqa: E402
from terratheme.core.io.images import read_image  # noqa: E402

DATA = HERE.parent.parent / "shared" / "data"
RESULTS = HERE / "results"
CLASSES = (1, 2, 3, 4, 5)
NAMES = ("building", "land", "road", "vegetation", "water")
HOLDOUT = 1


def load(folder: str, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(RGB uint8, mask uint8) of a shared data set's photo."""
    img = read_image(DATA / folder / "images" / name)
    mask = read_image(DATA / folder / "masks" / (Path(name).stem + ".png"))[:, :, 0]
    return np.ascontiguousarray(img[:, :, :3]), np.ascontiguousarray(mask)


def dubai(tiles: set[int]) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, photo, mask) of the Dubai photos of ``tiles``."""
    names = sorted(p.name for p in (DATA / "dubai" / "images").glob("*.jpg")
                   if int(p.stem.rsplit("t", 1)[1]) in tiles)
    return [(n, *load("dubai", n)) for n in names]


def timed(model, photo: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Labels, wall-clock and CPU seconds (all threads) of one ``predict``."""
    t, c = time.perf_counter(), time.process_time()
    labels = model.predict(photo).labels
    return labels, time.perf_counter() - t, time.process_time() - c


def evaluate(model, held: list, seen: bool, log) -> dict:
    """Dubai tile 1 (``seen``: in the model's training) and external scores and speed."""
    cm = np.zeros((5, 5), np.int64)
    px, secs, cpu = 0, 0.0, 0.0
    for _name, photo, mask in held:
        labels, dt, dc = timed(model, photo)
        cm += confusion(mask, labels, CLASSES)
        px, secs, cpu = px + mask.size, secs + dt, cpu + dc
    dubai_scores = scores(cm, NAMES)
    log(f"    dubai tile {HOLDOUT} ({'seen in training' if seen else 'held out'}): "
        f"mIoU {dubai_scores['miou']:.3f} {dubai_scores['iou']}")
    external = {}
    for folder, (photos, truth_map, pred_map) in COMMON.items():
        for name in photos:
            photo, mask = load(folder, name)
            labels, dt, dc = timed(model, photo)
            px, secs, cpu = px + mask.size, secs + dt, cpu + dc
            external[name] = shared_scores(mask, labels, truth_map, pred_map)
            log(f"    {name}: mIoU {external[name]['miou']:.3f} {external[name]['iou']}")
    return {"dubai_holdout": dubai_scores, "tile_1_seen_in_training": seen,
            "external": external,
            "external_mean_miou": float(np.mean([r["miou"] for r in external.values()])),
            "mpx_per_s": px / secs / 1e6, "mpx_per_cpu_s": px / cpu / 1e6,
            "load_average": os.getloadavg()[0]}


def chart(out: dict, path: Path) -> None:
    """Accuracy (held-out Dubai and external mIoU) against speed, one point per model."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for (name, row), colour in zip(out["models"].items(), ("C0", "C1", "C2", "C3"),
                                   strict=False):
        x = row["mpx_per_cpu_s"]
        seen = row.get("tile_1_seen_in_training", name == "forest")
        ax.scatter([x], [row["dubai_holdout"]["miou"]], c=colour, marker="o",
                   label=f"{name}: Dubai tile {HOLDOUT}"
                         + (" (seen in training)" if seen else " (held out)"))
        ax.scatter([x], [row["external_mean_miou"]], c=colour, marker="^",
                   label=f"{name}: LoveDA/Potsdam/DeepGlobe")
    ax.set_xscale("log")
    ax.set_xlabel("photo Mpx per CPU-second of predict")
    ax.set_ylabel("mIoU")
    ax.set_title("--model aerial: network vs forest")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="network,forest,forest-holdout",
                        help="rows to measure (comma-separated); the others are kept from "
                             "the results file")
    parser.add_argument("--models", type=Path, default=SHIPPED_MODELS_DIR,
                        help="folder of a candidate network's models.json (default: shipped)")
    args = parser.parse_args()
    only = set(args.only.split(","))
    if not (DATA / "dubai" / "images").is_dir():
        print(f"{DATA}: no shared data; nothing measured")
        return 0

    def log(msg: str) -> None:
        print(msg, flush=True)

    held = dubai({HOLDOUT})
    result_path = RESULTS / "classify_network.json"
    out = (json.loads(result_path.read_text()) if result_path.is_file()
           else {"holdout_tile": HOLDOUT, "models": {}})
    for name in ("network", "forest", "forest-holdout"):
        if name not in only:
            continue
        if name == "network":
            model = load_model("aerial", args.models)
            out["network_file"] = {"file": model.path.name,
                                   "bytes": model.path.stat().st_size}
            index = json.loads((args.models / MODELS_INDEX).read_text())
            seen = HOLDOUT in index["models"]["aerial"].get("tiles", [])
        elif name == "forest":
            model = load_model("aerial-forest")
            seen = True
        else:
            from train_aerial import options
            pairs = [(p, m) for _, p, m in dubai(set(range(1, 7)) - {HOLDOUT})]
            t = time.perf_counter()
            model = train_classifier(pairs, options())
            seen = False
            out["forest_holdout_training_s"] = time.perf_counter() - t
            log(f"forest-holdout trained in {out['forest_holdout_training_s']:.0f} s")
        log(f"{name}:")
        out["models"][name] = evaluate(model, held, seen, log)
        RESULTS.mkdir(exist_ok=True)
        result_path.write_text(json.dumps(out, indent=1) + "\n")
    chart(out, RESULTS / "classify_network.png")
    log(f"wrote {RESULTS / 'classify_network.json'} and .png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
