"""``terratheme export PROJECT OUTDIR --engine ...``: maps and textures for engines and GIS."""

from __future__ import annotations

import argparse

from terratheme.app.arg_types import int_tuple

NAME = "export"
HELP = ("export a project for Unity, Unreal, Godot Terrain3D or GIS: weight or control maps, "
        "theme textures, GeoTIFFs (docs/engines.md)")
ORDER = 25


_size = int_tuple("size", "WxH (integers)", 2)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("project", help="project file (.ttproj)")
    parser.add_argument("outdir", help="folder to write the export into (made if missing)")
    parser.add_argument("--engine", required=True, choices=["unity", "unreal", "godot", "geotiff"],
                        help="unity: RGBA splatmaps + terrain layers; unreal: weight map per "
                        "theme; godot: Terrain3D control map; geotiff: land-class map + baked "
                        "texture (COG)")
    parser.add_argument("--size", type=_size, metavar="WxH",
                        help="pixels of the whole weight/control map, corner to corner "
                        "(default: the engine's size nearest one pixel per texel; Terrain3D: "
                        "one pixel per grid vertex)")
    parser.add_argument("--style", choices=["project", "linear"], default="project",
                        help="weights (and the GIS texture and class map) in the project's own "
                        "style, shaped borders when it has them (default), or the paper's "
                        "linear barycentric weights")
    parser.add_argument("--tile", type=int, metavar="N",
                        help="cut the map into N x N tiles sharing their border pixels "
                        "(Unity: 16..4096, a power of two; Unreal: a recommended landscape size)")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from terratheme.app.outputs import check_outputs
    from terratheme.app.progress import progress_bar
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.exchange import (
        Engine,
        ExportOptions,
        WeightStyle,
        export_boundary,
        plan_export,
        write_export,
    )
    from terratheme.core.io.atomic import special_file
    from terratheme.core.render.project import load_checked_project

    outdir = Path(args.outdir)
    if outdir.exists() and not outdir.is_dir():
        kind = special_file(outdir) or "a file"
        raise TerrathemeError(f"{outdir}: is {kind}, not an output folder")
    project = load_checked_project(args.project)
    options = ExportOptions(Engine(args.engine), args.size, args.tile,
                            style=WeightStyle(args.style))
    plan = plan_export(project, options)
    check_outputs(plan.paths(outdir), inputs=[args.project], folder=outdir)
    with progress_bar(f"export {args.engine}", unit="part") as progress:
        paths = write_export(project, plan, outdir, progress=progress)
    if plan.layout is not None:
        (w, h), (kx, ky) = plan.layout.size, plan.layout.tiles
        tiles = f" in {kx} x {ky} tiles of {plan.layout.tile}" if plan.layout.tile else ""
        what = f"{w} x {h} map{tiles}"
    else:
        what = "land-class map and baked texture"
    shaped = export_boundary(project, options) is not None
    borders = plan.borders or ("shaped borders" if shaped else "linear weights")
    colour = ", colour map" if project.colour_map is not None else ""
    print(f"{outdir}: {args.engine} export, {what}, {borders}{colour}, {len(paths)} files "
          f"(manifest {paths[-1].name})")
    for note in plan.notes:
        print(f"  note: {note}")
    return 0
