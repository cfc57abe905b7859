"""``terratheme perspective INPUT OUT``: the texture on the ground, seen at a low angle."""

from __future__ import annotations

import argparse

NAME = "perspective"
HELP = ("render an image or a project on a ground plane seen in perspective, "
        "with the parallelogram anisotropic filter or a baseline")
ORDER = 60

METHODS = ["parallelogram", "trilinear", "aniso", "ewa", "bilinear", "nearest", "reference"]


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


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"size must be WxH, e.g. 640x360, got {text!r}") from exc
    return w, h


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", help="texture image, or a project (.ttproj: its render)")
    parser.add_argument("out", help="output image (.png, .tif, .exr ...)")
    parser.add_argument("--method", choices=METHODS, default="parallelogram",
                        help="texture filter (default: the seed's parallelogram filter)")
    parser.add_argument("--size", type=_size, default=(640, 360), metavar="WxH",
                        help="frame size in pixels (default 640x360)")
    view = parser.add_mutually_exclusive_group(required=True)
    view.add_argument("--camera", type=_floats((4, 6), "--camera"),
                      metavar="HEIGHT,PITCH,YAW,FOV[,X,Y]",
                      help="camera height in texels, pitch below horizontal, yaw clockwise "
                      "from north and horizontal field of view in degrees, optional "
                      "position in texels (default: the texture's centre)")
    view.add_argument("--mapping", type=_floats((9,), "--mapping"),
                      metavar="Au,Bu,Cu,Av,Bv,Cv,Az,Bz,Cz",
                      help="the nine plane-mapping coefficients (U, V in texels, "
                      "x, y in pixels, pixel centres at +0.5)")
    parser.add_argument("--max-anisotropy", type=float, default=16.0,
                        help="largest footprint elongation honoured (default 16)")
    parser.add_argument("--max-texture", type=int, default=4096, metavar="TEXELS",
                        help="downscale a larger texture to this many texels on its long "
                        "side first (the parallelogram family costs about 43 bytes per RGB "
                        "texel; default 4096); camera and mapping stay in input texels")


def run(args: argparse.Namespace) -> int:
    import numpy as np
    from tqdm import tqdm

    from core.errors import TerrathemeError
    from core.io.images import read_image, write_image
    from core.perspective import Camera, FilterOptions, Method, PlaneMapping, PreparedTexture

    # the texture: an image file, or a project's full render
    if str(args.input).lower().endswith(".ttproj"):
        from core.model.project import load_project
        from core.render.project import render_project

        texture = render_project(load_project(args.input))
    else:
        texture = read_image(args.input)
    # a texture too large for the prefiltered family is area-averaged down first
    if args.max_texture < 1:
        raise TerrathemeError(f"--max-texture must be at least 1, got {args.max_texture}")
    s = min(1.0, args.max_texture / max(texture.shape[:2]))
    if s < 1.0:
        import cv2

        full = texture.shape
        size = (max(1, round(full[1] * s)), max(1, round(full[0] * s)))
        texture = cv2.resize(texture, size, interpolation=cv2.INTER_AREA).reshape(
            size[1], size[0], full[2])
        sx, sy = size[0] / full[1], size[1] / full[0]
        print(f"note: texture {full[1]} x {full[0]} downscaled to {size[0]} x {size[1]} "
              "(--max-texture)")
    else:
        sx = sy = 1.0
    if args.camera is not None:
        c = args.camera
        x, y = (c[4] * sx, c[5] * sy) if len(c) == 6 else (None, None)
        view = Camera(height=c[0] * sx, pitch=c[1], yaw=c[2], fov=c[3], x=x, y=y)
    else:
        au, bu, cu, av, bv, cv, az, bz, cz = args.mapping
        view = PlaneMapping.from_sequence(
            [au * sx, bu * sx, cu * sx, av * sy, bv * sy, cv * sy, az, bz, cz])
    options = FilterOptions(method=Method(args.method), max_anisotropy=args.max_anisotropy)
    prepared = PreparedTexture(texture, options)
    with tqdm(total=args.size[1], desc="perspective", unit="row", leave=False) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        result = prepared.render(view, args.size, progress=progress)
    # back to the input's number type (integers were read as [0, 1])
    image = result.image
    if np.issubdtype(texture.dtype, np.integer):
        top = np.iinfo(texture.dtype).max
        image = np.clip(np.rint(image * top), 0, top).astype(texture.dtype)
    write_image(args.out, image)
    w, h = args.size
    print(f"{args.out}: {w} x {h} pixels, {args.method}, "
          f"{result.mean_reads:.1f} texels read per ground pixel, "
          f"{prepared.memory_bytes() / 2**20:.1f} MiB of prefiltered texture")
    return 0
