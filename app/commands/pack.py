"""``terratheme pack IN OUT``: pack an index image along a space-filling curve."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator

from terratheme.core.errors import TerrathemeError

NAME = "pack"
HELP = "pack an index image (<= 256 colours) into a random-access space-filling-curve layer"
ORDER = 50
#: Inputs larger than this (texels) are read band by band instead of whole.
STREAM_FROM = 1 << 28


def _tile(text: str) -> int:
    side = int(text)
    if side < 64 or side > 65536 or side & (side - 1):
        raise argparse.ArgumentTypeError(f"{text}: a power of two from 64 to 65536 expected")
    return side


@contextlib.contextmanager
def _naming(path: str) -> Iterator[None]:
    """The library's errors about the image being packed, with the file's name in front."""
    try:
        yield
    except TerrathemeError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise exc.at(path) from None


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
    parser.add_argument("--tile", type=_tile, metavar="N",
                        help="write a tiled container of N x N tiles (a power of two, 64 to "
                             "65536); images over 65536 a side are always tiled (65536)")


def run(args: argparse.Namespace) -> int:
    """Pack ``args.input`` into ``args.output`` and print a one-line summary."""
    import math

    from terratheme.app.outputs import check_outputs
    from terratheme.app.progress import progress_bar
    from terratheme.core.io.images import image_info
    from terratheme.core.packing import pack, pack_file
    from terratheme.core.packing.index_png import read_index_image

    check_outputs([args.output], inputs=[args.input])
    info = image_info(args.input)
    tile_bits = None if args.tile is None else int(math.log2(args.tile))
    big = info.width * info.height > STREAM_FROM or max(info.width, info.height) > 65536
    with progress_bar("pack") as progress, _naming(args.input):
        if big:
            # Band by band: memory holds one band of pixels and the runs.
            if args.reduce_palette:
                raise TerrathemeError(f"{args.input}: --reduce-palette needs the whole image in "
                                      "memory; reduce the palette first for an image this large")
            layer = pack_file(args.input, args.curve, tile_bits=tile_bits, progress=progress)
        else:
            image, colours = read_index_image(args.input)
            layer = pack(image, args.curve, reduce_palette=args.reduce_palette, colours=colours,
                         tile_bits=tile_bits, progress=progress)
    size = layer.save(args.output, format=args.format)
    h, w = layer.height, layer.width
    tiles = f", {layer.tiles_x} x {layer.tiles_y} tiles" if hasattr(layer, "tiles_x") else ""
    curve = layer.curve.name.lower() if hasattr(layer, "curve") else args.curve
    print(f"{args.output}: {w} x {h}{tiles}, {curve} curve, "
          f"{layer.palette.shape[0]} palette entries, {layer.run_count} runs, "
          f"{size} bytes ({args.format}, {8 * size / (w * h):.4f} bits/texel)")
    report = getattr(layer, "report", None)
    if report is not None:
        print(f"palette reduced from {report.colours_before} to {report.colours_after} colours: "
              f"max colour error {report.max_error:.2f}, mean {report.mean_error:.3f}")
    return 0
