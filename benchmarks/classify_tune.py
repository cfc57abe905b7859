"""Scribble variants on the tuning photos (Dubai parts 001-003), never the evaluation ones.

Run: ``PYTHONPATH=. python benchmarks/classify_tune.py VARIANT [VARIANT ...]``
(``--budget 0.005``, ``--draws 3``). Each variant (:data:`VARIANTS`) is trained on
simulated strokes (:func:`classify_eval.simulate_scribbles`, the benchmark's
strokes) of each of the 18 tuning photos and scored on the same photo, classes
1-5, for ``--draws`` independent draws (seeds apart from the evaluation
part's); prints the mean mIoU over photos per draw, their mean and spread, and
the prediction speed. The scribble defaults of :class:`SupervisedOptions` were
chosen here (``bench_classify.py`` keeps these photos out of its scribble rows).

Issue 17 at 0.5% (mean mIoU, 2 draws unless said; default 0.5916, per draw 0.5942
/ 0.5890; 3 draws 0.5863): adapt 0.5597, prior1 0.5884. Patched in, not kept (all
within noise or worse): strokes grown by 2 / 3 rings 0.5876 / 0.5865, grow
threshold 8 0.5818; a stroke labelling the superpixels it touches (SLIC of the
coarse Lab, 4 / 6 coarse px: 0.5287 / 0.5172; Felzenszwalb 0.5504); training
samples also from the photo shifted by half a block (3 draws, 4 / 2 offsets:
0.5769 / 0.5789); EDGE sigma_spatial 12 / sigma_colour 15 (3 draws) 0.5865 /
0.5833; 100 trees 0.5866, min_samples 2 0.5853 (3 draws); self-training with the
surest 30-50% of each class and classes kept 0.5756-0.5886; the forest refitted
on the strokes + the surest pseudo-labels 0.5828-0.5869; Extra-Trees
max_features 1 / log2 / 0.3 / 0.5 0.5772 / 0.5930 / 0.5870 / 0.5829, bootstrap
0.5879; prior counted on the regularised probabilities 0.5919 (power 1: 0.5879);
blocks a stroke covers under 3 / 6 / 12 of 64 pixels left out 0.5893 / 0.5882 /
0.5763. Issue 17 features (3 draws, default 0.5863: 0.5942 / 0.5890 / 0.5759):
morphological profile radii 2-4-8 (``FeatureOptions.profile_radii``) 0.5919
(0.6003 / 0.5930 / 0.5825), same speed; uniform LBP shares (patched in, commit
9355ce3) 0.5897 (0.5917 / 0.6005 / 0.5769) at 0.67x the speed.

Issue 17, random walker (Grady 2006, ``skimage.segmentation.random_walker``, mode
``cg_j``, tol 1e-3; pyamg is not installed, so no ``cg_mg``) on the coarse grid, seeds =
the strokes' coarse pixels (``coarse_mask``), patched in (a scratch harness on these
photos, draws and models that reproduces the default's per-draw figures exactly), not
kept. 3 draws, default 0.5863 (0.5942 / 0.5890 / 0.5759). Walker alone (Lab, beta 30)
0.4210. (a) Mixed into EDGE's output, 0.9 EDGE + 0.1 walker, beta 10 / 30 / 130: 0.5858
/ 0.5866 / 0.5862 (weight 0.05: 0.5862 / 0.5867 / 0.5863; 0.2: 0.5816 / 0.5841 /
0.5853); texture as a fourth channel 0.5867; grown seeds 0.5864; mixed into the raw
votes before EDGE 0.5858; EDGE x walker^0.1 0.5841 (^0.25 / ^0.5 on 6 photos, 1 draw:
-0.03 / -0.08). (b) Seeds = strokes + the surest 80% of each predicted class: walker
after EDGE 0.5695, in place of EDGE (seeds from the raw votes) 0.5694, half-and-half
with EDGE 0.5780. Grady's (2005) prior as a seeded twin plane (each pixel tied to a seed
of its arg-max class, more loosely where the forest's margin is small, kappa 5): after
EDGE 0.5835, before it 0.5844 (kappa 20 / 60 on 6 photos: -0.02 to -0.05 / -0.07 to
-0.16). (c) The forest's votes as walker channels beside Lab (0.7 EDGE + 0.3 walker):
Lab + 10 / 20 / 30 x raw votes at beta 60: 0.5851 / 0.5888 / 0.5887, at beta 130: 0.5864
/ 0.5887 (+0.0017 / +0.0019 / +0.0035 per draw) / 0.5879; beta 500 0.5706-0.5820; walker
weight 0.5 / 0.7 0.5691-0.5866 / 0.5537-0.5818; the votes alone as data 0.5833 (weight
0.1). Best +0.0024, under the forest-seed noise (~0.008 a draw): the more weight the
walker gets, the lower the mIoU. Its diffusion from 0.5% of short strokes knows colour
edges only, which EDGE already follows. Cost (same runs, load 2-4 on the 2 cores;
prediction 11-20 Mpx/s there): the stroke-seeded Lab walker adds 0.13-0.18 s per Mpx
(0.24-0.30x the speed), with forest seeds 0.012-0.03 s (0.65-0.82x: dense seeds, few CG
iterations), with the votes as channels 0.34-0.94 s (0.08-0.16x, 1-2.5 Mpx/s, under the
5 Mpx/s goal); and a model would have to keep its strokes to walk from them at
prediction.

Issue 17, learned patch words (Coates & Ng 2011), patched in (commit ec4a3a3, its
core/classify/patch_words.py and the variants here), not kept: K MiniBatchKMeans
centroids of contrast-normalised (each patch minus its mean, over sqrt(var + 2)),
ZCA-whitened (eps 0.1) 5 x 5 patches of the lightness (or Lab) block-averaged by
``level`` photo px, learned on the scribbled photo itself (20000 patches), each
patch encoded by the triangle activation max(0, mean(z) - z_k) of its centroid
distances, mean-pooled over the coarse pixel, K features appended. 2 draws,
default 0.5916 (0.5942 / 0.5890), prediction 9.1-15.2 Mpx/s in the same runs (load
0.7-5.4): L, K 32 at level 8 (40 px patches) 0.5928 (0.5978 / 0.5878) at 7.1 Mpx/s,
level 4 0.5956 (0.5966 / 0.5945) at 5.6; K 16 / 64 at level 8 0.5917 / 0.5908;
7 x 7 at level 8 0.5928; level 4 without contrast normalisation 0.5964; Lab patches
at level 4 / 8 0.5971 (0.6007 / 0.5935; 4.5 against 11.2 Mpx/s) / 0.5917. Lab at
level 4 over forest seeds 0 / 1 / 2: +0.0055 / +0.0068 / +0.0019 on the same seed's
default (seed 1 0.5923 -> 0.5991, seed 2 0.5905 -> 0.5924), mean +0.0047, under the
seed noise (~0.008 a draw), at 0.35-0.40x the speed (4.5-5.4 Mpx/s, the goal 5);
one photo per tile it gives +0.0008 over the three seeds (classify_tune_tiles.py).

Issue 17, what limits the strokes (tuning draw 0): the same features and forest
trained on the photo's full mask and scored on it reach 0.712 mean mIoU (0.615-0.880
by photo; pooled IoU building / land / road / vegetation / water 0.75 / 0.78 / 0.50 /
0.87 / 0.97) against the strokes' 0.59 (0.59 / 0.67 / 0.34 / 0.82 / 0.95): road is
predicted on 14.1% of the pixels (true 7.1%; 17.8% of land goes to road), building
loses 15.8% to land and 12.6% to road. Other classifiers on the strokes' samples
(scikit-learn, patched in, 2 draws, Extra-Trees default 0.5916 at 15.6 Mpx/s in the
same run): shrinkage LDA 0.5426, logistic regression 0.5454, RBF SVM (C 3,
balanced) 0.5754 at 5.5 Mpx/s, Extra-Trees averaged half-and-half with LDA /
logistic regression 0.5854 / 0.5859. Label spreading of the strokes over 10,000
coarse pixels of the photo (Zhou et al. 2004, scikit-learn LabelSpreading, knn
kernel k 7, alpha 0.2; branch h9-adapt, core/classify/spread.py, not kept), first
three tuning photos, mean of 3 draws, default 0.547 / 0.461 / 0.507: the surest
spread labels (peak >= 0.8) as extra forest samples 0.384 / 0.447 / 0.506; its
probabilities mixed 0.2 into the forest's 0.001 / 0.280 / 0.108 (the knn kernel
gives no distribution, NaN, to a pixel none of whose neighbours was reached).
Larger Gaussian scales did not help one photo per tile (classify_tune_tiles.py).
The class shares are a lever: the prior weights from the photo's true shares
(an oracle, 2 draws) give 0.6237 / 0.6230 / 0.6026 at power 0.5 / 0.75 / 1 against
the default's 0.5916 (classify-and-count shares, L1 error 0.341 from the true
ones). Adjusted classify-and-count (Forman 2008: the count corrected by the
forest's confusion rates, estimated by 3-fold cross-validation over whole strokes,
shares by non-negative least squares; patched in, not kept) is further off (L1
0.410 with arg-max counts, 0.399 with mean probabilities) and scores 0.5273 /
0.5084 (counts, power 0.75 / 1), 0.5228 / 0.4956 (probabilities): a stroke's
inside is classified far better than the photo's borders and mixed blocks, so
the rates measured on strokes do not hold on the photo. Closer shares alone do not
do it either (power 0.75, 2 draws): EM from uniform shares after 3 / 10 / 100 steps
(L1 0.298 / 0.305 / 0.308) 0.5888 / 0.5764 / 0.5751, the default's final labels
counted for a second round (L1 0.279) 0.5852, mean probabilities (L1 0.411) 0.5878.
Why (draw 0, the 9 tuning photos with all five classes, mean shares): true
building / land / road / vegetation / water 0.164 / 0.461 / 0.097 / 0.090 / 0.188,
counted 0.172 / 0.327 / 0.230 / 0.090 / 0.180, EM (3 steps) 0.157 / 0.364 / 0.237 /
0.075 / 0.167: every estimate from the forest's votes puts land's missing share in
road (2.4x its true share), the confusion itself, which the shares cannot undo.
The photo's own k-means clusters of its standardised coarse features (MiniBatchKMeans
on 20,000 of them) as one-hot forest features, patched in, 2 draws: K 12 / 24 0.5910
/ 0.5929 (0.5933 / 0.5888, 0.5950 / 0.5909) against 0.5916, within noise. Nor is it
where the strokes lie: the same pixel budget spent on random 8 x 8 blocks (two
rows of each labelled with the block's majority class, draw 0) scores 0.462
against the strokes' 0.594 (rare classes get few blocks, and many are mixed).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from classify_eval import confusion, draw_seeds, scores, simulate_scribbles
from terratheme.core.classify import SupervisedOptions, train_classifier

CLASSES = [1, 2, 3, 4, 5]
#: stroke draws of the tuning photos (the evaluation part draws from RNG_SEED + 1)
TUNE_SEED = 1017


def _features(**changes) -> SupervisedOptions:
    base = SupervisedOptions()
    return replace(base, features=replace(base.features, **changes))


#: the variants by name
VARIANTS = {
    "default": SupervisedOptions(),
    "position": SupervisedOptions().with_positions(),
    "prior1": SupervisedOptions(prior_power=1.0),
    "nogrow": SupervisedOptions(grow_colour=0.0),
    "nostructure": _features(structure=False),
    "adapt": SupervisedOptions(adapt=True),
    "profile-2-4-8": _features(profile_radii=(2, 4, 8)),
}


def tuning_photos(data: Path) -> list[str]:
    """The 18 tuning photos: Dubai parts 001-003 of every tile."""
    return sorted(p.name for p in (data / "dubai" / "images").glob("*.jpg")
                  if int(p.name[11:14]) <= 3)


def run(variants: dict[str, SupervisedOptions], budget: float, draws: int, log=print) -> dict:
    """Mean mIoU over the tuning photos per draw, for every variant -> rows."""
    import bench_classify as bench

    names = tuning_photos(bench.DATA)
    seeds = draw_seeds(TUNE_SEED, draws)
    mious = {v: [[] for _ in range(draws)] for v in variants}
    speed = {v: [0, 0.0] for v in variants}
    for name in names:
        photo, mask = bench.load("dubai", name)
        for d, seed in enumerate(seeds):
            rng = np.random.default_rng([*np.atleast_1d(seed), int(name[11:14]),
                                         int(name.split("t")[-1].split(".")[0])])
            scr = simulate_scribbles(mask, CLASSES, rng, budget)
            for v, opts in variants.items():
                model = train_classifier([(photo, scr)], opts)
                t = time.perf_counter()
                res = model.predict(photo)
                speed[v][1] += time.perf_counter() - t
                speed[v][0] += mask.size
                mious[v][d].append(scores(confusion(mask, res.labels, CLASSES), CLASSES)["miou"])
        log(f"  {name}: " + ", ".join(f"{v} {np.mean([m[-1] for m in mious[v]]):.3f}"
                                      for v in variants))
    rows = {}
    for v in variants:
        per_draw = [float(np.mean(m)) for m in mious[v]]
        rows[v] = {"mean": float(np.mean(per_draw)), "spread": float(np.std(per_draw)),
                   "per_draw": [round(x, 4) for x in per_draw],
                   "mpx_per_s": speed[v][0] / max(speed[v][1], 1e-9) / 1e6}
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("variants", nargs="+", choices=sorted(VARIANTS))
    parser.add_argument("--budget", type=float, default=0.005)
    parser.add_argument("--draws", type=int, default=3)
    args = parser.parse_args(argv)
    rows = run({v: VARIANTS[v] for v in args.variants}, args.budget, args.draws)
    for v, r in rows.items():
        print(f"{v:16s} mean mIoU {r['mean']:.4f} (+/- {r['spread']:.4f} over draws; "
              f"{r['per_draw']})  {r['mpx_per_s']:.2f} Mpx/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
