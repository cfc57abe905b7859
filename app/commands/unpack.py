"""``terratheme unpack IN OUT``: a packed layer back to an image file."""

from __future__ import annotations

import argparse

NAME = "unpack"
HELP = "unpack a space-filling-curve layer back to an image file"
ORDER = 51


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``terratheme unpack``."""
    parser.add_argument("input", metavar="IN", help="packed layer file")
    parser.add_argument("output", metavar="OUT", help="image to write (PNG, TIFF, ...)")


def run(args: argparse.Namespace) -> int:
    """Unpack ``args.input`` into the image ``args.output``."""
    from core.io.images import write_image
    from core.packing import PackedLayer

    layer = PackedLayer.load(args.input)
    write_image(args.output, layer.unpack())
    print(f"{args.output}: {layer.width} x {layer.height}, {layer.channels} channel(s)")
    return 0
