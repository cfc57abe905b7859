"""``terratheme info IN``: what a packed layer or a project holds."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "info"
HELP = ("describe a packed layer (size, curve, palette, runs) or a project (grid, themes, "
        "colour map, style, bytes); --json for machines")
ORDER = 52


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``terratheme info``."""
    parser.add_argument("input", metavar="IN", help="packed layer (.ttpack) or project (.ttproj)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--runs", action="store_true",
                        help="packed layer: include the runs: S (1-based step of each run's last "
                             "texel), P (decodes the layer; without it only the header is read)")


def run(args: argparse.Namespace) -> int:
    """Print what ``args.input`` holds."""
    import json

    if Path(args.input).suffix.lower() == ".ttproj":
        info = _project_info(args)
    else:
        info = _layer_info(args)
    if args.json:
        print(json.dumps(info))
        return 0
    for key, value in info.items():
        if isinstance(value, list) and len(value) > 16:
            value = f"{value[:16]} ... ({len(value)} entries)"
        elif isinstance(value, str) and not value.isprintable():
            value = repr(value)  # text from the file: no control characters to the terminal
        print(f"{key}: {value}")
    return 0


def _layer_info(args: argparse.Namespace) -> dict:
    """The header, palette and checksum (fast whatever the size); the runs with ``--runs``."""
    import dataclasses

    from terratheme.core.packing import layer_info

    # The header, palette and checksum only (numba is not even imported).
    info = dataclasses.asdict(layer_info(args.input))
    if args.runs:
        from terratheme.core.errors import TerrathemeError
        from terratheme.core.packing import PackedLayer

        if info["tiles"] > 1:
            raise TerrathemeError(f"{args.input}: a tiled container; --runs lists one layer's runs")
        layer = PackedLayer.load(args.input)
        info["S"] = layer.S.tolist()
        info["P"] = layer.P.tolist()
    return info


def _project_info(args: argparse.Namespace) -> dict:
    """Grid, themes, colour map, render style and bytes of a project."""
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.fidelity import texture_cost
    from terratheme.core.render.project import load_checked_project, photo_extent, project_style

    if args.runs:
        raise TerrathemeError("--runs lists a packed layer's runs; a project has none")
    project = load_checked_project(args.input)
    grid = project.grid
    gh, gw = grid.cells_shape
    style = project_style(project)
    colour_map = project.colour_map
    return {
        "texture_size": list(grid.texture_size),
        "extent": list(photo_extent(project)),
        "cell": list(grid.cell),
        "vertices": [gw + 1, gh + 1],
        "themes": [{"index": k, "name": t.name, "size": list(t.texture.shape[1::-1]),
                    "source": t.source} for k, t in enumerate(project.library)],
        "blend": "shaped" if style.boundary is not None else style.blend.value,
        "colour_map": None if colour_map is None else {
            "scale": colour_map.scale, "size": list(colour_map.pixels.shape[1::-1]),
            "codec": colour_map.codec, "upsample": colour_map.upsample,
            "sharpen": colour_map.sharpen, "predicted": colour_map.colours is not None},
        "georeference": project.metadata.get("georeference"),
        "source_photo": project.metadata.get("source_photo"),
        "layers": [name for name in ("photo", "scribbles") if getattr(project, name) is not None],
        **texture_cost(project).as_dict(),
    }
