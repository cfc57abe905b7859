"""``terratheme new MAP [MAP ...] PROJECT --themes ...``: a project from an index image or maps."""

from __future__ import annotations

import argparse
from pathlib import Path

from terratheme.app.arg_types import int_tuple

NAME = "new"
HELP = ("make a project from an index image (vertex = pixel), or from Unity splatmaps, weight "
        "maps or a Terrain3D control map, with shipped themes chosen by name; or back from an "
        "export (its folder or manifest)")
ORDER = 10


_cell = int_tuple("cell", "N or NxM", 2, one_for_all=True)


def _step(text: str) -> int:
    try:
        step = int(text)
    except ValueError:
        step = 0
    if step < 1:
        raise argparse.ArgumentTypeError(f"--step must be a whole number of at least 1, "
                                         f"got {text!r}")
    return step


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "inputs", nargs="+", metavar="MAP",
        help="index image: one pixel per grid vertex, grey values = theme numbers (0 = first of "
        "--themes) or the chosen themes' display colours; or engine maps (see --from); or an "
        "export's folder or manifest",
    )
    parser.add_argument("project", help="project file to write (.ttproj)")
    parser.add_argument("--themes",
                        help="comma-separated shipped theme names in index order, "
                        "e.g. water,sand,forest (not for --from export: its own themes)")
    parser.add_argument("--cell", type=_cell, default=(16, 16), metavar="N[xM]",
                        help="texels per cell: N columns x M rows (default 16)")
    parser.add_argument("--from", dest="kind", default="index",
                        choices=["index", "splatmap", "weights", "terrain3d", "export"],
                        help="what MAP is: an index image (default); Unity splatmaps (RGBA, 4 "
                        "themes each, in order); one grey weight map per theme (Unreal); a "
                        "Terrain3D control map (32-bit float EXR). Maps: strongest theme per "
                        "pixel, ties to the lower theme. export: a terratheme export's folder "
                        "or manifest (the default for a folder or a .json), whose project comes "
                        "back exactly: grid, themes (those cut from the photo too), colour map")
    parser.add_argument("--step", type=_step, default=1, metavar="S",
                        help="engine maps: map pixels per cell (a vertex every S pixels, the "
                        "map's edges on vertices; default 1 = every pixel a vertex)")


def _from_export(args: argparse.Namespace) -> int:
    """The project an export carries, saved as PROJECT."""
    from terratheme.app.outputs import check_outputs
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.exchange.carried import (
        carried_project_path,
        export_manifest,
        project_from_export,
    )
    from terratheme.core.model.project import save_project

    if len(args.inputs) != 1:
        raise TerrathemeError(f"--from export reads one export (its folder or manifest), got "
                              f"{len(args.inputs)}")
    if args.themes is not None or args.step != 1:
        raise TerrathemeError("an export brings its own themes and grid: --themes and --step "
                              "are for index images and engine maps")
    manifest = export_manifest(args.inputs[0])
    check_outputs([args.project], inputs=[manifest, carried_project_path(manifest)])
    project = project_from_export(manifest)
    project.metadata.update({"created_by": "terratheme new", "source_export": str(manifest)})
    save_project(args.project, project)
    gh, gw = project.grid.indices.shape
    w, h = project.grid.texture_size
    colour = "" if project.colour_map is None else ", colour map"
    print(f"{args.project}: {gw} x {gh} vertices, cell {project.grid.cell[0]}x"
          f"{project.grid.cell[1]}, renders to {w} x {h}, themes "
          f"{', '.join(project.library.names)}{colour} (from {manifest})")
    return 0


def run(args: argparse.Namespace) -> int:
    from terratheme.app.outputs import check_outputs
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.exchange.carried import MANIFEST_GLOB
    from terratheme.core.exchange.maps_to_grid import grid_from_maps
    from terratheme.core.io.images import image_info, read_image
    from terratheme.core.model.grid import IndexGrid, validate_cell
    from terratheme.core.model.index_image import project_from_index_image
    from terratheme.core.model.project import ThematicTexture, check_vertex_count, save_project
    from terratheme.core.themes.library import shipped_theme_library

    first = Path(args.inputs[0])
    if args.kind == "export" or (args.kind == "index" and len(args.inputs) == 1 and (
            first.is_dir() or first.suffix.lower() == ".json")):
        return _from_export(args)
    if args.themes is None:
        raise TerrathemeError(f"--themes is needed with --from {args.kind} (the shipped themes "
                              "in index order, see terratheme themes)")
    check_outputs([args.project], inputs=args.inputs)
    validate_cell(args.cell)
    names = [n.strip() for n in args.themes.split(",") if n.strip()]
    if not names:
        raise TerrathemeError(f"--themes {args.themes!r} names no theme (see terratheme themes)")
    library = shipped_theme_library().select(names)
    single = args.kind in ("index", "terrain3d")
    if single and len(args.inputs) != 1:
        raise TerrathemeError(f"--from {args.kind} reads one map, got {len(args.inputs)}")
    if args.kind == "weights" and len(args.inputs) != len(library):
        raise TerrathemeError(f"--from weights needs one weight map per theme: "
                              f"{len(args.inputs)} maps for {len(library)} themes")
    sources = [str(p) for p in args.inputs]
    # The grid's size from the first map's header, before any map is read.
    info, step = image_info(sources[0]), max(1, args.step)
    try:
        check_vertex_count(((info.height - 1) // step + 1) * ((info.width - 1) // step + 1))
    except TerrathemeError as exc:
        raise TerrathemeError(f"{sources[0]}: {info.width} x {info.height} pixels: {exc}") from None
    metadata = {"created_by": "terratheme new"}
    if args.kind == "index":
        if args.step != 1:
            raise TerrathemeError("--step is for engine maps; index images have a pixel per vertex")
        metadata["source_index_image"] = sources[0]
        image = read_image(sources[0])
        try:
            project = project_from_index_image(image, library, args.cell, metadata)
        except TerrathemeError as exc:
            raise TerrathemeError(f"{sources[0]}: {exc}") from None
    else:
        # Headers first (types, channels, one size), then band by band: memory is the grid.
        indices = grid_from_maps(sources, args.kind, len(library), args.step)
        metadata.update({"source_maps": sources, "source_kind": args.kind})
        try:
            grid = IndexGrid(indices, args.cell)
            project = ThematicTexture(grid, library, metadata)
        except TerrathemeError as exc:
            raise TerrathemeError(f"{', '.join(sources)}: {exc}") from None
    save_project(args.project, project)
    w, h = project.grid.texture_size
    print(f"{args.project}: {project.grid.indices.shape[1]} x {project.grid.indices.shape[0]} "
          f"vertices, cell {args.cell[0]}x{args.cell[1]}, renders to {w} x {h}, "
          f"themes {', '.join(library.names)}")
    if args.kind != "index":
        # Maps of an export: the exact grid, themes and colour map are one command away.
        beside = sorted(Path(sources[0]).parent.glob(MANIFEST_GLOB))
        if len(beside) == 1:
            print(f"  note: these maps belong to the export {beside[0].parent}: 'terratheme new "
                  f"{beside[0].parent} PROJECT' brings back its project exactly (grid, themes, "
                  "colour map)")
    return 0
