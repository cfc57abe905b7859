"""``terratheme info IN``: header, palette and runs of a packed layer."""

from __future__ import annotations

import argparse

NAME = "info"
HELP = "describe a packed layer (size, curve, palette, runs); --json for machines"
ORDER = 52


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``terratheme info``."""
    parser.add_argument("input", metavar="IN", help="packed layer file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--runs", action="store_true",
                        help="include the runs: S (1-based step of each run's last texel), P "
                             "(decodes the layer; without it only the header is read)")


def run(args: argparse.Namespace) -> int:
    """Print what ``args.input`` holds."""
    import dataclasses
    import json

    from core.packing import layer_info

    # The header, palette and checksum only: fast whatever the layer's size.
    info = dataclasses.asdict(layer_info(args.input))
    if args.runs:
        from core.errors import TerrathemeError
        from core.packing import PackedLayer

        if info["tiles"] > 1:
            raise TerrathemeError(f"{args.input}: a tiled container; --runs lists one layer's runs")
        layer = PackedLayer.load(args.input)
        info["S"] = layer.S.tolist()
        info["P"] = layer.P.tolist()
    if args.json:
        print(json.dumps(info))
        return 0
    for key, value in info.items():
        if key in ("palette", "S", "P") and len(value) > 16:
            value = f"{value[:16]} ... ({len(value)} entries)"
        print(f"{key}: {value}")
    return 0
