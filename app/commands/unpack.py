"""``terratheme unpack IN OUT``: a packed layer back to an image file, band by band."""

from __future__ import annotations

import argparse

NAME = "unpack"
HELP = ("unpack a space-filling-curve layer to an image file (.png: a palette PNG of the "
        "indices; .tif/.exr: the values, tiled; both streamed band by band)")
ORDER = 51


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``terratheme unpack``."""
    parser.add_argument("input", metavar="IN", help="packed layer file")
    parser.add_argument("output", metavar="OUT", help="image to write (PNG, TIFF, ...)")


def run(args: argparse.Namespace) -> int:
    """Unpack ``args.input`` into the image ``args.output``."""
    from terratheme.app.outputs import check_image_outputs, check_outputs
    from terratheme.core.packing import load_layer, write_layer_image
    from terratheme.core.packing.export import check_layer_image_path

    check_outputs([args.output], inputs=[args.input])
    check_layer_image_path(args.output)
    layer = load_layer(args.input)
    check_image_outputs([args.output], channels=layer.channels)
    kind = write_layer_image(layer, args.output)
    print(f"{args.output}: {layer.width} x {layer.height}, {layer.channels} channel(s), {kind}")
    return 0
