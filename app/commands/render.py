"""``terratheme render PROJECT OUT``: render a project's texture to an image file."""

from __future__ import annotations

import argparse
import contextlib
import math

from terratheme.app.arg_types import int_tuple, unit_fraction

NAME = "render"
HELP = "render a project (.ttproj) to an image, whole or a region, full size or scaled down"
ORDER = 20

#: full-resolution .tif renders above this many texels are streamed (--tiled): 16384^2
STREAM_TEXELS = 1 << 28


_region = int_tuple("region", "x,y,w,h (integers)", 4, ",")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("project", help="project file (.ttproj)")
    parser.add_argument("out", help="output image (.png, .tif, .jpg, .exr ...)")
    parser.add_argument("--region", type=_region, metavar="X,Y,W,H",
                        help="render only this window (full-resolution texels; default: the "
                             "photo's extent, or the whole texture of a hand-made project)")
    parser.add_argument("--scale", type=unit_fraction("scale"), default=1.0,
                        help="output pixels per texel, in (0, 1] (overview render below 1)")
    parser.add_argument("--blend", choices=["linear", "histogram", "shaped"], default=None,
                        help="default: the project's own style (shaped borders for converted "
                             "photos, the paper's linear ramp for hand-made maps); linear: the "
                             "paper's; histogram: histogram-preserving (Heitz & Neyret 2018); "
                             "shaped: borders shaped by the themes and noise")
    parser.add_argument("--tiled", action="store_true",
                        help="write a tiled GeoTIFF with overviews band by band (bounded "
                             "memory; Cloud Optimized layout), at full resolution; the default "
                             f"for .tif outputs of more than {STREAM_TEXELS:,} texels")
    parser.add_argument("--gpu", action="store_true",
                        help="render through the OpenGL shaders (headless EGL; Mesa's llvmpipe "
                             "without a GPU), in the same style: at scale 1 the same texels as "
                             "the CPU render, below 1 each pixel's area mean")
    parser.add_argument("--packed", nargs="?", const="", default=None, metavar="LAYER",
                        help="with --gpu: read the index grid from a packed layer (.ttpack) "
                             "in the shaders, never unpacked (default LAYER: PROJECT's stem + "
                             ".ttpack, what convert writes); the layer's indices are drawn, the "
                             "project gives the themes, cell size and style")


def run(args: argparse.Namespace) -> int:
    from terratheme.app.outputs import check_image_outputs, check_outputs
    from terratheme.app.progress import progress_bar
    from terratheme.core.io.georef import (
        stale_world_file,
        world_file_name,
        write_georeferenced,
    )
    from terratheme.core.io.memory import RENDER_BYTES_PER_PIXEL, check_fits
    from terratheme.core.render.boundary import BoundaryOptions
    from terratheme.core.render.inputs import validate_region
    from terratheme.core.render.project import (
        load_checked_project,
        photo_extent,
        project_style,
        render_georeference,
        render_project,
    )
    from terratheme.core.render.renderer import BlendMode, RenderOptions

    packed = _packed_path(args)
    check_outputs([args.out, world_file_name(args.out)],  # the world file a render may get
                  inputs=[args.project] + ([packed] if packed else []))
    check_image_outputs([args.out], channels=3)
    project = load_checked_project(args.project)
    _check_world_frame(args.project, project)
    grid = _packed_grid(packed, project) if packed else project.grid
    if args.blend is None:
        options = project_style(project)
    elif args.blend == "shaped":
        options = RenderOptions(boundary=BoundaryOptions())
    else:
        options = RenderOptions(blend=BlendMode(args.blend))
    style = "shaped" if options.boundary is not None else options.blend.value
    # The region is checked before the progress bar starts, not in the render.
    region = validate_region(args.region or (0, 0, *photo_extent(project)),
                             project.grid.texture_size)
    if _streamed(args, region):
        return _render_tiled(args, project, region, options, style)
    # The whole image is held: refused at once when it cannot fit (a small project with
    # large cells renders to any size).
    check_fits(args.project, max(1, math.ceil(region[2] * args.scale)),
               max(1, math.ceil(region[3] * args.scale)), RENDER_BYTES_PER_PIXEL,
               remedy="render it in regions (--region), scaled down (--scale) or to a .tif "
               "(--tiled, streamed)")
    gpu = _gpu_renderer(project) if args.gpu else None
    with progress_bar("render", unit="tile" if gpu else "band") as progress:
        if gpu is not None:
            image = _render_gpu(gpu, project, grid, region, args.scale, options, progress)
        else:
            image = render_project(project, region, args.scale, options=options,
                                   progress=progress)
    h, w = image.shape[:2]
    georeference = render_georeference(project, region, (w, h))
    stale = stale_world_file(args.out, georeference)
    made = write_georeferenced(args.out, image, georeference)
    if stale is not None:  # it placed the image just replaced; this one has no georeference
        with contextlib.suppress(FileNotFoundError):
            stale.unlink()
    geo = " with its georeference" if made else ""
    how = ", GPU from the packed layer" if packed else ", GPU" if gpu else ""
    print(f"{args.out}: {w} x {h} texels ({style} blend{how}){geo}")
    for extra in made:
        if str(extra) != str(args.out):
            print(f"  world file: {extra}")
    return 0


def _check_world_frame(path: str, project) -> None:
    """Refuse, before the work, a georeference no GIS could place the render by (a zero
    pixel size, corners beyond floating point), as export does: the render would carry it."""
    from terratheme.core.errors import CorruptFileError, TerrathemeError
    from terratheme.core.exchange.layout import world_frame

    try:
        world_frame(project.metadata.get("georeference"), project.grid.texture_size)
    except TerrathemeError as exc:
        raise CorruptFileError(f"{path}: {exc}") from None


def _gpu_renderer(project):
    """The project's themes on the GPU (fails with one line where no OpenGL context exists)."""
    from terratheme.core.gpu import GpuRenderer

    return GpuRenderer(project.library.textures)


def _packed_path(args: argparse.Namespace) -> str | None:
    """The packed layer ``--packed`` names (its default beside the project), or None."""
    from pathlib import Path

    from terratheme.core.errors import TerrathemeError

    if args.packed is None:
        return None
    if not args.gpu:
        raise TerrathemeError("--packed reads the index grid on the GPU: add --gpu")
    return args.packed or str(Path(args.project).with_suffix(".ttpack"))


def _packed_grid(path: str, project):
    """The packed layer at ``path``, checked to be the size of the project's vertex grid."""
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.packing import PackedLayer, load_layer

    layer = load_layer(path)
    if not isinstance(layer, PackedLayer):
        raise TerrathemeError(f"{path}: a tiled container; the GPU reads single packed layers")
    gh, gw = project.grid.indices.shape
    if (layer.width, layer.height) != (gw, gh):
        raise TerrathemeError(f"{path}: a {layer.width} x {layer.height} layer, but the "
                              f"project's grid has {gw} x {gh} vertices")
    return layer


def _render_gpu(gpu, project, grid, region, scale: float, style, progress):
    """``grid`` (the project's, or its packed layer) through the shaders in ``style``."""
    from terratheme.core.gpu import GpuRenderOptions

    try:
        return gpu.render(grid, project.grid.cell, region=region, scale=scale, progress=progress,
                          options=GpuRenderOptions.from_render_options(style),
                          colour_map=project.colour_map)
    finally:
        gpu.release()


def _streamed(args: argparse.Namespace, region) -> bool:
    """Whether to stream a tiled GeoTIFF: ``--tiled``, or a large full-resolution .tif."""
    from pathlib import Path

    from terratheme.core.errors import TerrathemeError

    tif = Path(args.out).suffix.lower() in (".tif", ".tiff")
    if not args.tiled:
        return tif and args.scale == 1.0 and not args.gpu and \
            region[2] * region[3] > STREAM_TEXELS
    if not tif:
        raise TerrathemeError(f"{args.out}: --tiled writes a GeoTIFF: name it .tif")
    if args.scale != 1.0 or args.gpu:
        raise TerrathemeError("--tiled renders at full resolution on the CPU, with overviews "
                              "in the file: drop --scale and --gpu")
    return True


def _render_tiled(args, project, region, options, style: str) -> int:
    """The streamed output: tiled GeoTIFF with overviews, band by band (bounded memory)."""
    from terratheme.app.progress import progress_bar
    from terratheme.core.exchange.texture_tiff import write_texture_tiff

    with progress_bar("render (tiled)", unit="band") as progress:
        (w, h), overviews = write_texture_tiff(project, args.out, region, options=options,
                                               progress=progress)
    geo = " with its georeference" if project.metadata.get("georeference") else ""
    print(f"{args.out}: {w} x {h} texels ({style} blend), tiled GeoTIFF with {overviews} "
          f"overview{'s' if overviews != 1 else ''}{geo}")
    return 0
