"""``terratheme pack IN OUT``: pack an index image along a space-filling curve."""

from __future__ import annotations

import argparse

NAME = "pack"
HELP = "pack an index image (<= 256 colours) into a random-access space-filling-curve layer"
ORDER = 50


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``terratheme pack``."""
    parser.add_argument("input", metavar="IN",
                        help="index or palette image (PNG, TIFF, ...); a palette PNG's indices "
                             "are packed, its colours kept for display")
    parser.add_argument("output", metavar="OUT", help="packed layer file to write")
    parser.add_argument("--curve", choices=["hilbert", "morton", "auto"], default="hilbert",
                        help="scan curve; auto keeps whichever gives fewer runs (default hilbert)")
    parser.add_argument("--format", choices=["compact", "seed"], default="compact",
                        help="compact (entropy-coded, default) or the seed's plain varint layout")
    parser.add_argument("--reduce-palette", action="store_true",
                        help="reduce images with more than 256 colours instead of refusing")


def run(args: argparse.Namespace) -> int:
    """Pack ``args.input`` into ``args.output`` and print a one-line summary."""
    from tqdm import tqdm

    from app.outputs import check_outputs
    from core.packing import pack
    from core.packing.index_png import read_index_image

    check_outputs([args.output], inputs=[args.input])
    image, colours = read_index_image(args.input)
    with tqdm(total=1, desc="pack", unit="curve", leave=False) as bar:
        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        layer = pack(image, args.curve, reduce_palette=args.reduce_palette, colours=colours,
                     progress=progress)
    size = layer.save(args.output, format=args.format)
    h, w = layer.height, layer.width
    print(f"{args.output}: {w} x {h}, {layer.curve.name.lower()} curve, "
          f"{layer.palette.shape[0]} palette entries, {layer.run_count} runs, "
          f"{size} bytes ({args.format}, {8 * size / (w * h):.4f} bits/texel)")
    if layer.report is not None:
        r = layer.report
        print(f"palette reduced from {r.colours_before} to {r.colours_after} colours: "
              f"max colour error {r.max_error:.2f}, mean {r.mean_error:.3f}")
    return 0
