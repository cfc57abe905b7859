"""``terratheme classify``: label an orthophoto's pixels with themes.

Unsupervised (k-means, K from the data or ``--themes K``) unless scribbles,
training pairs or a saved model are given, in which case Extra-Trees do
the job (see :mod:`core.classify`).
"""

from __future__ import annotations

import argparse
import re
from fractions import Fraction
from pathlib import Path

from terratheme.app.arg_types import add_legend_option

NAME = "classify"
HELP = "classify an orthophoto into themes (unsupervised, or from scribbles/label masks)"
ORDER = 30


def _themes(value: str) -> str | int:
    if value == "auto":
        return value
    try:
        k = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{value}' is not 'auto' or a number") from None
    if not 1 <= k <= 255:
        raise argparse.ArgumentTypeError(f"--themes must be 1..255, not {k}")
    return k


def _class_value(value: str) -> int:
    try:
        k = int(value)
    except ValueError:
        k = -1
    if not 0 <= k <= 255:
        raise argparse.ArgumentTypeError(f"a mask class value is a whole number 0..255, "
                                         f"not {value!r}")
    return k


#: ``--cache-size``: a number with an optional binary unit (K, M, G, T; ``B`` or ``iB`` after)
_SIZE = re.compile(r"(\d+(?:\.\d*)?|\.\d+)\s*([kmgt]?)(?:i?b)?", re.IGNORECASE)
#: the largest ``--cache-size``: 1024T
MAX_CACHE_BYTES = 1 << 50


def _cache_size(text: str) -> int:
    """Bytes of ``--cache-size``: ``2G`` is 2 GiB, ``1.5g`` 1.5 GiB, ``4096`` bytes; 1..1024T."""
    match = _SIZE.fullmatch(text.strip())
    if match is None:
        raise argparse.ArgumentTypeError(f"--cache-size must be a number of bytes with an "
                                         f"optional unit K, M, G or T (e.g. 2G, 500M), not "
                                         f"{text!r}")
    unit = 1 << (10 * " kmgt".index(match.group(2).lower() or " "))
    # digits bounded before the exact arithmetic (a huge number is refused, not computed)
    size = 0 if len(match.group(1)) > 40 else int(Fraction(match.group(1)) * unit)
    if not 1 <= size <= MAX_CACHE_BYTES:
        raise argparse.ArgumentTypeError(f"--cache-size must be from one byte to 1024T, "
                                         f"not {text!r}")
    return size


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the command's arguments."""
    parser.add_argument("photo", metavar="PHOTO", help="orthophoto (PNG, JPEG, TIFF, EXR, ...)")
    parser.add_argument("-o", "--output", metavar="LABELS.png", required=True,
                        help="8-bit label image, the photo's size: a .png is a palette PNG "
                             "(values are the class numbers, shown in theme colours), other "
                             "formats are grey")
    parser.add_argument("--scribbles", metavar="MASK",
                        help="brush strokes on PHOTO: 0 = unlabelled, k > 0 = class k")
    parser.add_argument("--train", nargs=2, action="append", default=[],
                        metavar=("PHOTO", "MASK"),
                        help="another photo with its label mask (repeatable)")
    parser.add_argument("--ignore", type=_class_value, nargs="+", default=[], metavar="K",
                        help="mask class values to treat as unlabelled (e.g. 6 7)")
    parser.add_argument("--themes", type=_themes, default=None, metavar="auto|K",
                        help="unsupervised: number of themes, or 'auto' (default)")
    parser.add_argument("--confidence", metavar="CONF.png",
                        help="write the per-pixel confidence (8-bit 0..255 for PNG/JPEG, "
                             "float 0..1 for TIFF/EXR)")
    parser.add_argument("--position", action="store_true",
                        help="with --scribbles: where the strokes lie counts as evidence too "
                             "(helps photos of large whole regions; the model then fits "
                             "PHOTO only)")
    add_legend_option(parser, "names of the mask classes, kept in --model-out (convert --model "
                              "then names its themes by them)")
    parser.add_argument("--model-out", metavar="M", help="save the trained classifier")
    parser.add_argument("--model", metavar="M",
                        help="classify with a saved classifier or a shipped one by name (aerial)")
    parser.add_argument("--cache-dir", type=Path, default=None, metavar="DIR",
                        help="keep the training pairs' samples and the fitted model in DIR, by "
                             "content: training again on the same pairs and options (another "
                             "photo to classify) skips their features and the fit")
    parser.add_argument("--cache-size", metavar="SIZE", type=_cache_size, default=None,
                        help="bound of the --cache-dir folder, e.g. 500M or 2G (binary units; "
                             "default 2G): the least recently used entries are removed first")


def _read_photo(path: str):
    """A photo for the classifier: 8- and 16-bit and float pixels as they are, other
    integer types (32-bit, signed) converted to 8 bits on reading, as convert's
    ``read_photo`` does (which converts floats too)."""
    import numpy as np
    from terratheme.core.io.images import Bands, read_image

    photo = read_image(path, bands=Bands.PHOTO)
    if photo.dtype.kind in "iu" and photo.dtype not in (np.uint8, np.uint16):
        photo = read_image(path, dtype=np.uint8, bands=Bands.PHOTO)
    return photo


def label_palette():
    """(256, 3) uint8 colours for label images, all distinct (so values read back exactly).

    0 (unlabelled, no data) is black; 1..9 are the shipped themes' display
    colours in ``themes.json`` order; the rest are spread over hue and value.
    """
    import cv2
    import numpy as np
    from terratheme.core.themes.library import shipped_theme_library

    colours = [(0, 0, 0), *(tuple(int(c) for c in t.colour) for t in shipped_theme_library())]
    step = 0
    while len(colours) < 256:
        # Golden-ratio hue walk, three brightness levels (OpenCV hue is 0..179).
        hsv = np.array([[[int(step * 0.618034 * 180) % 180, 200, (255, 190, 130)[step % 3]]]],
                       np.uint8)
        rgb = tuple(int(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0])
        if rgb not in colours:
            colours.append(rgb)
        step += 1
    return np.array(colours[:256], np.uint8)


def _training_cache(folder: Path | None, size: int | None):
    """The training cache in ``folder`` bounded to ``size`` bytes (None: the default),
    checked before any work; None without a folder."""
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.io.disk_cache import DEFAULT_CACHE_BYTES, DiskCache

    if folder is None:
        if size is not None:
            raise TerrathemeError("--cache-size bounds the --cache-dir folder: give "
                                  "--cache-dir too")
        return None
    cache = DiskCache(folder, DEFAULT_CACHE_BYTES if size is None else size)
    why = cache.unusable()
    if why is not None:
        raise TerrathemeError(f"--cache-dir {folder}: cannot use the folder ({why})")
    return cache


def run(args: argparse.Namespace) -> int:
    """Run the command; returns the exit status."""
    import numpy as np
    from terratheme.app.outputs import check_image_outputs, check_mask_sizes, check_outputs
    from terratheme.app.progress import StageBar
    from terratheme.core.classify import (
        SupervisedOptions,
        classify_unsupervised,
        load_model,
        train_classifier,
    )
    from terratheme.core.classify.network import NetworkClassifier
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.io.atomic import file_set
    from terratheme.core.io.images import image_info, read_class_mask, write_image
    from terratheme.core.io.legend import read_legend
    from terratheme.core.io.memory import (
        CLASSIFY_BYTES_PER_PIXEL,
        CLASSIFY_FOREST_BYTES_PER_PIXEL,
        CLASSIFY_NETWORK_BYTES_PER_PIXEL,
        check_fits,
    )
    from terratheme.core.packing.export import check_layer_image_path

    supervised = bool(args.scribbles or args.train)
    if args.model and supervised:
        raise TerrathemeError("--model classifies with a saved model: do not combine it with "
                              "--scribbles or --train")
    if args.themes is not None and (supervised or args.model):
        raise TerrathemeError("--themes is for unsupervised classification; the classes of "
                              "--scribbles/--train/--model come from the masks")
    if args.position and (not args.scribbles or args.train):
        raise TerrathemeError("--position needs --scribbles and no --train: a position in "
                              "another photo says nothing about this one")
    if args.model_out and not supervised:
        raise TerrathemeError("--model-out needs training data (--scribbles or --train)")
    if args.cache_dir is not None and not supervised:
        raise TerrathemeError("--cache-dir keeps training samples and models: it needs "
                              "--scribbles or --train")
    if args.legend and not (supervised or args.model):
        raise TerrathemeError("--legend names the classes of --scribbles, --train or --model")
    # Every output path is checked before any work (and before the labels are written).
    check_outputs([args.output, args.confidence, args.model_out],
                  inputs=[args.photo, args.scribbles, args.model, args.legend,
                          *(p for pair in args.train for p in pair)])
    check_image_outputs([args.output, args.confidence], channels=1)
    check_layer_image_path(args.output, "the class numbers")
    label_suffix = Path(args.output).suffix.lower()
    # Masks of the wrong size are refused from the headers, before any pixel is read.
    check_mask_sizes([(args.photo, args.scribbles)] if args.scribbles else [], "scribble mask")
    check_mask_sizes([tuple(pair) for pair in args.train])
    legend = read_legend(args.legend) if args.legend else {}
    cache = _training_cache(args.cache_dir, args.cache_size)

    info = image_info(args.photo)
    # A saved model first (a small file): its kind sets the memory the photo needs.
    model = load_model(args.model) if args.model else None
    if isinstance(model, NetworkClassifier):
        per_pixel = CLASSIFY_NETWORK_BYTES_PER_PIXEL
    elif model is not None or supervised:
        per_pixel = CLASSIFY_FOREST_BYTES_PER_PIXEL
    else:
        per_pixel = CLASSIFY_BYTES_PER_PIXEL
    check_fits(args.photo, info.width, info.height, per_pixel)  # before reading
    photo = _read_photo(args.photo)
    # Read and train first, so input errors come before any progress bar is drawn.
    if supervised:
        pairs = []
        if args.scribbles:
            pairs.append((photo, read_class_mask(args.scribbles)))
        for train_photo, train_mask in args.train:
            pairs.append((_read_photo(train_photo), read_class_mask(train_mask)))
        options = SupervisedOptions(ignore_classes=tuple(args.ignore))
        model = train_classifier(pairs, options.with_positions(args.position), cache=cache)
        if cache is not None and cache.hits["model"]:
            print(f"model from the cache {args.cache_dir}")
    if model is not None and legend:
        model.name_classes(legend)

    bars: list = []

    def progress(done: int, total: int) -> None:
        if not bars:
            bars.append(StageBar(total=total, desc="classify", unit="tile"))
        bars[0].n = done
        bars[0].refresh()

    try:
        if model is not None:
            result = model.predict(photo, progress=progress)
        else:
            themes = "auto" if args.themes is None else args.themes
            result = classify_unsupervised(photo, themes=themes, progress=progress)
    finally:
        for bar in bars:
            bar.close()

    # Labels as a palette PNG (values stay the class numbers) or a grey image; the outputs
    # as one set (all replaced or none).
    palette = label_palette() if label_suffix == ".png" else None
    # EXR has no 8-bit integers (OpenImageIO would scale them to 0..1 halves): 32-bit UINT.
    labels = result.labels[:, :, None].astype(np.uint32 if label_suffix == ".exr" else np.uint8)
    writers = [(args.output, lambda p: write_image(p, labels, palette=palette))]
    if args.confidence:
        if args.confidence.lower().endswith((".tif", ".tiff", ".exr")):
            conf = result.confidence
        else:
            conf = np.round(result.confidence * 255.0).astype(np.uint8)
        writers.append((args.confidence, lambda p: write_image(p, conf[:, :, None])))
    if args.model_out:
        writers.append((args.model_out, model.save))
    # The summary's class shares before anything is written (a band of rows at a time: a
    # failure after the set is committed would report an error over written files).
    rows = max(1, (1 << 22) // max(1, result.labels.shape[1]))
    counts = sum((np.bincount(result.labels[y: y + rows].ravel(), minlength=256)
                  for y in range(0, result.labels.shape[0], rows)), np.zeros(256, np.int64))
    with file_set([path for path, _ in writers]):
        for path, write in writers:
            write(path)  # to the set's temporary (atomic_path), its errors naming path
    names = (model.class_names if model is not None else None) or {}
    shown = ", ".join(f"{k}{' ' + names[k] if k in names else ''}: "
                      f"{counts[k] / result.labels.size:.1%}" for k in result.classes)
    print(f"{args.output}: {len(result.classes)} classes ({shown})")
    return 0
