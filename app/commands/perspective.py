"""``terratheme perspective INPUT OUT``: the texture on the ground, seen at a low angle."""

from __future__ import annotations

import argparse
import os
import re
import threading
import time
from pathlib import Path

from terratheme.app.arg_types import int_tuple

NAME = "perspective"
HELP = ("render an image or a project on a ground plane seen in perspective, "
        "with the parallelogram anisotropic filter or a baseline")
ORDER = 60

METHODS = ["parallelogram", "trilinear", "aniso", "ewa", "bilinear", "nearest", "reference"]
EPILOG = """\
examples:
  terratheme perspective out/sample.ttproj out/low.png
      the default view: from beyond the texture's south edge, looking north,
      about 10 degrees down, the horizon in the frame
  terratheme perspective photo.png low.png --camera 40,8,30,60 --size 1280x720
      40 texels up, 8 degrees down, heading 30 degrees east of north, 60-degree view
  terratheme perspective tex.png low.png --mapping -6,0,960,0,0,2000,0,0.05,1
      the nine plane-mapping coefficients (negative numbers are fine)

The prefiltered family of the texture is kept in a cache folder
($XDG_CACHE_HOME/terratheme/families, else ~/.cache/terratheme/families;
--cache-dir, --no-cache), so the next preview of the same texture starts at once.
"""
#: arguments that are numbers or comma-separated numbers (argparse would take
#: "-60,10,0,60" for an option; this makes it a value, as it does for "-60")
NUMBERS = re.compile(r"^-[\d.]+([eE][-+]?\d+)?(,[-+]?[\d.]+([eE][-+]?\d+)?)*$")
#: seconds without progress before the first-run compile note
COMPILE_NOTE_AFTER = 2.0


def _floats(count: tuple[int, ...], what: str):
    def parse(text: str) -> list[float]:
        try:
            vals = [float(v) for v in text.split(",")]
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"{what} must be numbers separated by commas, "
                                             f"got {text!r}") from exc
        if len(vals) not in count:
            want = " or ".join(str(c) for c in count)
            raise argparse.ArgumentTypeError(f"{what} needs {want} numbers, got {len(vals)}")
        return vals

    return parse


_size = int_tuple("size", "WxH, e.g. 640x360", 2)


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/terratheme/families``, else ``~/.cache/terratheme/families``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "terratheme" / "families"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.epilog = EPILOG
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser._negative_number_matcher = NUMBERS  # values such as -60,10,0,60
    parser.add_argument("input", help="texture image, or a project (.ttproj: its texture, "
                        "rendered at the detail the frame needs)")
    parser.add_argument("out", help="output image (.png, .tif, .exr ...)")
    parser.add_argument("--method", choices=METHODS, default="parallelogram",
                        help="texture filter (default: the seed's parallelogram family, read "
                        "by exact coverage)")
    parser.add_argument("--size", type=_size, default=(640, 360), metavar="WxH",
                        help="frame size in pixels (default 640x360)")
    view = parser.add_mutually_exclusive_group()
    view.add_argument("--camera", type=_floats((4, 6), "--camera"),
                      metavar="HEIGHT,PITCH,YAW,FOV[,X,Y]",
                      help="camera height in texels, pitch below horizontal, yaw clockwise "
                      "from north and horizontal field of view in degrees, optional "
                      "position in texels (default: the texture's centre). Without "
                      "--camera or --mapping: a low-angle view of the whole texture")
    view.add_argument("--mapping", type=_floats((9,), "--mapping"),
                      metavar="Au,Bu,Cu,Av,Bv,Cv,Az,Bz,Cz",
                      help="the nine plane-mapping coefficients (U, V in texels, "
                      "x, y in pixels, pixel centres at +0.5)")
    parser.add_argument("--max-anisotropy", type=float, default=16.0,
                        help="largest cell elongation kept in the family (default 16)")
    parser.add_argument("--gpu", action="store_true",
                        help="a project's frame through the GPU renderer (OpenGL on EGL; Mesa's "
                             "llvmpipe without a GPU): its own style, mipmapped themes, "
                             "--max-anisotropy probes; --method and --max-texture do not apply")
    parser.add_argument("--max-texture", type=int, default=4096, metavar="TEXELS",
                        help="use the texture reduced to at most this many texels on its long "
                        "side (the family costs about 24 bytes per RGB texel; default 4096); "
                        "camera and mapping stay in input texels")
    cache = parser.add_mutually_exclusive_group()
    cache.add_argument("--cache-dir", type=Path, default=None, metavar="DIR",
                       help="folder of prefiltered families (default: see below)")
    cache.add_argument("--no-cache", action="store_true",
                       help="build the family afresh and keep it only for this run")


def _warm_up(texture, options, project=None) -> None:
    """Load (or, on a first run, compile) the kernels this run needs on tiny inputs,
    saying so in one line when that takes long (a compile)."""
    import numpy as np
    from terratheme.core.perspective import Camera, PreparedTexture

    def note() -> None:
        print("note: compiling the preview kernels (first run only, a minute or two; "
              "`python -m terratheme.app.warmup` does it at install)", flush=True)

    timer = threading.Timer(COMPILE_NOTE_AFTER, note)
    timer.daemon = True
    timer.start()
    try:
        tiny = np.ascontiguousarray(texture[:8, :8])
        PreparedTexture(tiny, options).render(Camera(height=4, pitch=20), (8, 8), options)
        if project is not None:
            from terratheme.core.render.project import render_project

            w, h = project.grid.texture_size
            render_project(project, (0, 0, min(8, w), min(8, h)), 1.0)
            render_project(project, (0, 0, min(16, w), min(16, h)), 0.5)
    finally:
        timer.cancel()


def _family_cache(args: argparse.Namespace):
    """The family cache, checked before any work: a folder named by ``--cache-dir`` must
    be usable; the default one is only an optimisation (unusable: no cache, and a note)."""
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.io.disk_cache import DiskCache

    if args.no_cache:
        return None
    folder = Path(args.cache_dir) if args.cache_dir else default_cache_dir()
    cache = DiskCache(folder)
    why = cache.unusable()
    if why is None:
        return cache
    if args.cache_dir:
        raise TerrathemeError(f"--cache-dir {folder}: cannot use the folder ({why})")
    print(f"note: the family cache {folder} cannot be used ({why}); the family is not kept")
    return None


def run(args: argparse.Namespace) -> int:
    import numpy as np
    from terratheme.app.outputs import check_image_outputs, check_outputs
    from terratheme.app.progress import progress_bar
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.io.images import read_image, write_image
    from terratheme.core.io.memory import PERSPECTIVE_BYTES_PER_PIXEL, check_fits
    from terratheme.core.perspective import (
        Camera,
        FilterOptions,
        Method,
        PlaneMapping,
        PreparedTexture,
        check_size,
    )
    from terratheme.core.perspective.mapping import camera_mapping, overview_camera, scaled_view
    from terratheme.core.perspective.project_view import project_texture, texture_scale
    from terratheme.core.perspective.texture import stored_texture

    check_outputs([args.out], inputs=[args.input])
    check_image_outputs([args.out], channels=3)
    check_size(args.size)  # before the warm-up and the camera's mapping
    if not args.gpu:  # the CPU filters hold per-pixel arrays of the whole frame
        check_fits("the frame", *args.size, PERSPECTIVE_BYTES_PER_PIXEL,
                   remedy="choose a smaller --size (or --gpu for a project)")
    cache = _family_cache(args)
    if args.max_texture < 1:
        raise TerrathemeError(f"--max-texture must be at least 1, got {args.max_texture}")
    options = FilterOptions(method=Method(args.method), max_anisotropy=args.max_anisotropy)
    is_project = str(args.input).lower().endswith(".ttproj")
    if is_project:
        from terratheme.core.render.project import load_checked_project

        project = load_checked_project(args.input)
        full_size = project.grid.texture_size
    else:
        texture = read_image(args.input)
        try:
            stored_texture(texture)  # NaN / out-of-range values, before the warm-up
        except TerrathemeError as exc:
            raise TerrathemeError(f"{args.input}: {exc}") from None
        full_size = (texture.shape[1], texture.shape[0])
    # the view, in texels of the full texture
    if args.camera is not None:
        c = args.camera
        x, y = (c[4], c[5]) if len(c) == 6 else (None, None)
        view = Camera(height=c[0], pitch=c[1], yaw=c[2], fov=c[3], x=x, y=y)
    elif args.mapping is not None:
        view = PlaneMapping.from_sequence(args.mapping)
    else:
        view = overview_camera(full_size)
    if args.gpu:
        return _run_gpu(args, project if is_project else None, view)
    t0 = time.perf_counter()
    if is_project:
        # a tiny texture of the project's type for the warm-up
        _warm_up(np.zeros((8, 8, 3), np.uint8), options, project)
        # the texture at the detail the frame needs
        texture, view = project_texture(project, view, args.size, args.max_texture)
    else:
        _warm_up(texture, options)
        mapping = view if isinstance(view, PlaneMapping) else camera_mapping(view, args.size,
                                                                             full_size)
        s = texture_scale(mapping, args.size, full_size, args.max_texture)
        if s < 1.0:
            import cv2

            size = (max(1, round(full_size[0] * s)), max(1, round(full_size[1] * s)))
            texture = cv2.resize(texture, size, interpolation=cv2.INTER_AREA).reshape(
                size[1], size[0], -1)
            view = scaled_view(view, size[0] / full_size[0], size[1] / full_size[1])
    if (texture.shape[1], texture.shape[0]) != tuple(full_size):
        print(f"note: texture {full_size[0]} x {full_size[1]} used at "
              f"{texture.shape[1]} x {texture.shape[0]} (the detail the frame needs, "
              "--max-texture)")
    with progress_bar("prefiltering", None, unit="cell", disable=None) as built:
        prepared = PreparedTexture(texture, options, progress=built, cache=cache)
    with progress_bar("perspective", args.size[1], unit="row", disable=None) as rendered:
        result = prepared.render(view, args.size, progress=rendered)
    seconds = time.perf_counter() - t0
    # back to the input's number type (integers were read as [0, 1])
    image = result.image
    if np.issubdtype(texture.dtype, np.integer):
        top = np.iinfo(texture.dtype).max
        image = np.clip(np.rint(image * top), 0, top).astype(texture.dtype)
    write_image(args.out, image)
    w, h = args.size
    cached = {True: ", family from the cache", False: ", family cached",
              None: ""}[prepared.cache_hit]
    print(f"{args.out}: {w} x {h} pixels, {args.method}, "
          f"{result.mean_reads:.1f} texels read per ground pixel, "
          f"{prepared.memory_bytes() / 2**20:.1f} MiB of prefiltered texture{cached}, "
          f"{seconds:.2f} s")
    return 0


def _run_gpu(args: argparse.Namespace, project, view) -> int:
    """``--gpu``: one frame of a project through :func:`core.gpu.render_perspective_gpu`."""
    from terratheme.core.errors import TerrathemeError
    from terratheme.core.gpu import GroundOptions, render_perspective_gpu
    from terratheme.core.io.images import write_image

    if project is None:
        raise TerrathemeError("--gpu renders projects (.ttproj): give a project, or leave out "
                              "--gpu for an image")
    t0 = time.perf_counter()
    frame = render_perspective_gpu(project, view, args.size,
                                   options=GroundOptions(max_anisotropy=args.max_anisotropy))
    write_image(args.out, frame)
    w, h = args.size
    print(f"{args.out}: {w} x {h} pixels on the GPU, {time.perf_counter() - t0:.2f} s")
    return 0
