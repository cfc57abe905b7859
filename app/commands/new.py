"""``terratheme new INDEX_IMAGE PROJECT --themes ...``: a project from an index image."""

from __future__ import annotations

import argparse

NAME = "new"
HELP = "make a project from an index image (vertex = pixel) and shipped themes chosen by name"
ORDER = 10


def _cell(text: str) -> tuple[int, int]:
    try:
        parts = [int(v) for v in text.lower().split("x")]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"cell must be N or NxM, got {text!r}") from exc
    if len(parts) == 1:
        parts *= 2
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"cell must be N or NxM, got {text!r}")
    return parts[0], parts[1]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "index_image",
        help="one pixel per grid vertex: grey values = theme numbers (0 = first of --themes), "
        "or colours = the chosen themes' display colours",
    )
    parser.add_argument("project", help="project file to write (.ttproj)")
    parser.add_argument("--themes", required=True,
                        help="comma-separated shipped theme names in index order, "
                        "e.g. water,sand,forest")
    parser.add_argument("--cell", type=_cell, default=(16, 16), metavar="N[xM]",
                        help="texels per cell: N columns x M rows (default 16)")


def run(args: argparse.Namespace) -> int:
    from core.io.images import read_image
    from core.model.index_image import project_from_index_image
    from core.model.project import save_project
    from core.themes.library import shipped_theme_library

    names = [n.strip() for n in args.themes.split(",") if n.strip()]
    library = shipped_theme_library().select(names)
    image = read_image(args.index_image)
    project = project_from_index_image(
        image, library, args.cell, {"source_index_image": str(args.index_image),
                                    "created_by": "terratheme new"},
    )
    save_project(args.project, project)
    w, h = project.grid.texture_size
    print(f"{args.project}: {project.grid.indices.shape[1]} x {project.grid.indices.shape[0]} "
          f"vertices, cell {args.cell[0]}x{args.cell[1]}, renders to {w} x {h}, "
          f"themes {', '.join(library.names)}")
    return 0
