"""``terratheme convert``: orthophoto -> thematic texture project, preview and packed layer.

Runs :mod:`core.convert.photo` (or the tiled path with ``--tile``) with a progress bar
and writes, by default beside PROJECT, ``<stem>_preview.png`` (with a world file for a
GeoTIFF photo), ``<stem>.ttpack`` and its colour map ``<stem>_colour.<codec>``.
"""

from __future__ import annotations

import argparse
import contextlib
import re

from terratheme.app.arg_types import add_legend_option
from terratheme.core.errors import TerrathemeError

NAME = "convert"
HELP = "turn an orthophoto into a thematic texture project (+ preview render, packed layer)"
ORDER = 40


def _number(kind: type, low: float, high: float, what: str, *, words: tuple[str, ...] = (),
            open_low: bool = False):
    """An argparse type: one of ``words``, or a ``kind`` number in ``[low, high]``."""

    def parse(value: str):
        if value in words:
            return value
        try:
            v = kind(value)
        except ValueError:
            accepted = " or ".join([*words, "a number"])
            raise argparse.ArgumentTypeError(f"'{value}' is not {accepted}") from None
        if not (low < v if open_low else low <= v) or v > high:
            lo = "(" if open_low else "["
            raise argparse.ArgumentTypeError(f"{what} must be in {lo}{low:g}, {high:g}], not {v}")
        return v

    return parse


_cell = _number(int, 1, 4096, "--cell", words=("auto",))
_agreement = _number(float, 0.0, 1.0, "--target-agreement", open_low=True)
_share = _number(float, 0.0, 1.0, "--class-target")
_colour_map = _number(float, 0.0, 100.0, "--colour-map target", words=("auto", "off"),
                      open_low=True)
_budget = _number(float, 0.0, 1.0, "--budget", open_low=True)


def _class_number(text: str) -> int | None:
    """``text`` as a class number 1..255 in ASCII digits, else None (no int() of a
    thousand digits, nor of other scripts' digits)."""
    if not re.fullmatch(r"[0-9]{1,6}", text, re.ASCII):
        return None
    number = int(text)
    return number if 1 <= number <= 255 else None


def parse_themes(text: str) -> str | int | list[str] | dict[int, str]:
    """Parse ``--themes``: ``auto``, ``K``, ``name,name,...`` or ``1=name,2=name``."""
    text = text.strip()
    if not text:
        raise TerrathemeError("--themes is empty (use auto, a number, or theme names)")
    if text.lower() == "auto":
        return "auto"
    if text.isdigit():
        k = _class_number(text)
        if k is None:
            raise TerrathemeError(f"--themes {text[:20]!r}: the number of themes must be 1..255")
        return k
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if all("=" in p for p in parts):
        out: dict[int, str] = {}
        for p in parts:
            key, name = (s.strip() for s in p.split("=", 1))
            number = _class_number(key)
            if number is None:
                raise TerrathemeError(f"--themes {p[:40]!r}: class must be a number 1..255")
            if number in out:
                raise TerrathemeError(f"--themes {text[:80]!r}: class {number} is named twice")
            out[number] = name
        return out
    if any("=" in p for p in parts):
        raise TerrathemeError(f"--themes {text!r}: mix of names and class=name pairs")
    return parts


def _check_theme_names(themes) -> None:
    """Unknown shipped theme names are refused before any work."""
    from terratheme.core.themes.library import shipped_theme_library

    if isinstance(themes, str | int):
        return
    library = shipped_theme_library()
    for name in themes.values() if isinstance(themes, dict) else themes:
        library.index_of(name)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the command's arguments."""
    parser.add_argument("photo", metavar="PHOTO", help="orthophoto (PNG, JPEG, TIFF/GeoTIFF, EXR)")
    parser.add_argument("project", metavar="PROJECT", help="output project file (.ttproj)")
    parser.add_argument("--cell", type=_cell, default="auto", metavar="auto|N",
                        help="cell size in texels, or 'auto' (default): the largest cell whose "
                             "label view keeps --target-agreement of the photo's labels")
    parser.add_argument("--themes", default="auto", metavar="auto|K|name,name,...",
                        help="'auto' (default): as many themes as the photo needs, cut from it; "
                             "K: that many; names: shipped themes (water,sand,town,...) matched "
                             "to the classes by colour; 1=name,2=name: scribble classes by name")
    parser.add_argument("--target-agreement", type=_agreement, default=0.9, metavar="T",
                        help="share of pixels whose theme the grid must keep (default 0.9)")
    parser.add_argument("--preview", metavar="PNG",
                        help="preview render (default: PROJECT's stem + _preview.png)")
    parser.add_argument("--packed", metavar="FILE",
                        help="packed index layer (default: PROJECT's stem + .ttpack)")
    parser.add_argument("--scribbles", metavar="MASK",
                        help="brush strokes on PHOTO (0 = unlabelled, k > 0 = class k): "
                             "supervised classification")
    parser.add_argument("--model", metavar="M",
                        help="classify with a saved classifier (terratheme classify --model-out) "
                             "or a shipped one by name (aerial: building, land, road, vegetation, "
                             "water; the themes take its class names)")
    add_legend_option(parser, "names of the classes of --scribbles or --model: the themes take "
                              "them")
    parser.add_argument("--tile", type=int, metavar="N",
                        help="photos larger than memory: classify and vote tile by tile "
                             "(N pixels a side; unsupervised themes fitted on the whole photo in "
                             "a first pass; themes, --cell auto and the colour map's "
                             "scale chosen once on 25 windows spread over it; --workers or "
                             "--scheduler run the tiles on a dask cluster, same result)")
    parser.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                        help="with --tile: run the tile jobs on this running dask.distributed "
                             "scheduler; its workers read PHOTO from its absolute path (a file "
                             "system they all see) and need terratheme installed; tls://HOST:PORT "
                             "with --tls-ca-file and --tls-cert (as dask scheduler's options)")
    parser.add_argument("--tls-ca-file", metavar="PEM",
                        help="with --scheduler tls://...: the CA the scheduler's certificate is "
                             "checked against")
    parser.add_argument("--tls-cert", metavar="PEM",
                        help="with --scheduler tls://...: this client's certificate")
    parser.add_argument("--tls-key", metavar="PEM",
                        help="with --scheduler tls://...: this client's key (if not in --tls-cert)")
    parser.add_argument("--workers", type=_number(int, 1, 1024, "--workers"), metavar="K",
                        help="with --tile: run the tile jobs on a local cluster of K worker "
                             "processes (one thread each; TLS with credentials made for the run, "
                             "no dashboard); same result as without")
    parser.add_argument("--curve", metavar="PNG",
                        help="also write the agreement / bytes vs cell size chart (cell auto; "
                             ".png, .svg or .pdf)")
    parser.add_argument("--class-target", type=_share, default=0.5, metavar="T",
                        help="with --cell auto, every class of at least 0.5%% of the photo keeps "
                             "this IoU with its label view, so thin classes such as roads do "
                             "not vanish (default 0.5; 0 = off)")
    parser.add_argument("--colour-map", type=_colour_map, default="auto", metavar="auto|off|T",
                        help="auto (default): a colour map coded for a byte budget of 0.04 "
                             "bits per photo pixel (grid + map), the themes carrying only fine "
                             "detail; T: the coarsest map whose colour error (dE8) stays under "
                             "T, whole themes; off: the paper's pure rule")
    parser.add_argument("--budget", type=_budget, metavar="BPP",
                        help="with --colour-map auto: bits per photo pixel for the packed grid "
                             "and the colour map together (default 0.04); more gives truer "
                             "colours and edges up close (the map itself stays at 1/6-1/3 of "
                             "the photo's resolution, drawn up to twice as fine)")
    parser.add_argument("--boundary", choices=["shaped", "linear"], default="shaped",
                        help="shaped (default): borders of a few texels shaped by the themes and "
                             "noise; linear: the paper's ramp across the cell")
    parser.add_argument("--specks", choices=["remove", "keep"], default="remove",
                        help="remove (default): a vertex none of whose 8 neighbours shares its "
                             "theme takes theirs (it would render as a diamond); keep: the vote "
                             "as it is")


#: the chart formats of ``--curve`` (matplotlib's, chosen by the name's suffix)
CHART_SUFFIXES = (".png", ".svg", ".pdf")


def _curve_chart(choice, path: str) -> None:
    import io
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from terratheme.core.io.atomic import write_bytes_atomic

    cells = [p.cell for p in choice.curve]
    fig, ax = plt.subplots(figsize=(6, 3.6), dpi=110)
    ax.plot(cells, [p.agreement for p in choice.curve], "o-", label="agreement")
    ax.axhline(choice.target, color="grey", ls="--", lw=1, label=f"target {choice.target:g}")
    ax.axvline(choice.cell[0], color="tab:green", lw=1, label=f"chosen cell {choice.cell[0]}")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("cell size (texels)")
    ax.set_ylabel("label agreement")
    ax2 = ax.twinx()
    ax2.plot(cells, [p.grid_bytes for p in choice.curve], "s:", color="tab:red", label="bytes")
    ax2.set_yscale("log")
    ax2.set_ylabel("grid bytes (1 per vertex)")
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    # Drawn in memory, then written whole: matplotlib's PDF writer, failing on a full
    # disk, raised an AttributeError of its own in place of the OSError.
    chart = io.BytesIO()
    fig.savefig(chart, format=Path(path).suffix.lower()[1:])
    plt.close(fig)
    write_bytes_atomic(path, chart.getvalue())


def run(args: argparse.Namespace) -> int:
    """Run the command; returns the exit status."""
    from pathlib import Path

    from terratheme.app.outputs import (
        check_file_names,
        check_image_outputs,
        check_mask_sizes,
        check_outputs,
    )
    from terratheme.app.progress import StageBar
    from terratheme.core.convert.photo import (
        ConvertOptions,
        convert_photo,
        output_files,
        read_photo,
        write_outputs,
    )
    from terratheme.core.fidelity import texture_cost
    from terratheme.core.io.images import image_info, read_class_mask
    from terratheme.core.io.memory import CONVERT_BYTES_PER_PIXEL, check_fits

    check_file_names([args.project, args.preview, args.packed])  # before Path drops a '/'
    project = Path(args.project)
    if project.suffix.lower() != ".ttproj":
        raise TerrathemeError(f"{project}: the project file must end in .ttproj")
    preview = args.preview or str(project.with_name(project.stem + "_preview.png"))
    packed = args.packed or str(project.with_suffix(".ttpack"))
    themes = parse_themes(args.themes)
    _check_theme_names(themes)
    if args.curve and args.cell != "auto":
        raise TerrathemeError("--curve charts the automatic cell choice: it needs --cell auto")
    if args.budget is not None and args.colour_map != "auto":
        raise TerrathemeError("--budget sets the bytes of --colour-map auto: it does not go "
                              f"with --colour-map {args.colour_map}")
    if args.curve and Path(args.curve).suffix.lower() not in CHART_SUFFIXES:
        raise TerrathemeError(f"{args.curve}: the chart is written as "
                              f"{', '.join(CHART_SUFFIXES)}; name it so")
    if (args.scheduler or args.workers) and args.tile is None:
        raise TerrathemeError("--scheduler and --workers run the tiled path: give --tile N")
    if args.scheduler and args.workers:
        raise TerrathemeError("--scheduler joins a running cluster, --workers starts one: "
                              "pick one")
    tls = [args.tls_ca_file, args.tls_cert, args.tls_key]
    if any(tls) and not args.scheduler:
        raise TerrathemeError("--tls-ca-file, --tls-cert and --tls-key are for --scheduler "
                              "tls://HOST:PORT")
    # Output paths checked (and their folders made) before any work.
    check_outputs([*output_files(project, preview_path=preview, packed_path=packed), args.curve],
                  inputs=[args.photo, args.scribbles, args.model, args.legend, *tls])
    check_image_outputs([preview], channels=3)
    check_mask_sizes([(args.photo, args.scribbles)] if args.scribbles else [], "scribble mask")
    _check_georeference(args.photo)
    legend = _read_legend(args, themes)
    if args.tile is not None:
        return _run_tiled(args, project, preview, packed, themes, legend)
    model = None
    if args.model:
        if args.scribbles:
            raise TerrathemeError("--model and --scribbles both give the classes: pick one")
        model = _load_model(args.model, legend)
    info = image_info(args.photo)
    check_fits(args.photo, info.width, info.height, CONVERT_BYTES_PER_PIXEL,  # before reading
               remedy="convert it tile by tile (--tile 2048)")
    photo, meta = read_photo(args.photo)
    scribbles = read_class_mask(args.scribbles) if args.scribbles else None
    if (scribbles is not None or model is not None) and isinstance(themes, int):
        raise TerrathemeError("--themes K is for unsupervised classification; with --scribbles "
                              "or --model the classes are given (use auto or 1=name,2=name)")
    colour, boundary = _style(args)
    options = ConvertOptions(
        cell=args.cell, themes=themes, target_agreement=args.target_agreement,
        class_target=args.class_target, colour_map=colour, boundary=boundary,
        full_curve=bool(args.curve), keep_specks=args.specks == "keep")
    with StageBar(total=100, desc="convert", unit="%") as bar:

        def progress(done: int, total: int) -> None:
            bar.n = min(100, done * 100 // max(total, 1))
            bar.refresh()

        result = convert_photo(photo, options, scribbles=scribbles, model=model,
                               class_names=legend, metadata=meta, progress=progress)
        bar.set_description("write")
        written = write_outputs(result.project, project, preview_path=preview,
                                packed_path=packed)
    if args.curve and result.choice is not None:
        _curve_chart(result.choice, args.curve)
        written["curve"] = Path(args.curve)
    grid = result.project.grid
    gh, gw = grid.cells_shape
    h, w = photo.shape[:2]
    names = ", ".join(result.project.library.names)
    k = len(result.project.library)
    cost = texture_cost(result.project)
    fitted = result.colour
    cmap = None if fitted is None else fitted.colour_map
    colour = ("no colour map" if cmap is None else
              f"colour map 1/{cmap.coded_scale}"
              + (f" drawn at 1/{cmap.scale}" if cmap.upsample > 1 else "")
              + (f" sharpened {cmap.sharpen / 4:g}" if cmap.sharpen else "")
              + (" over the grid's colours" if cmap.colours is not None else "")
              + f" (dE8 {fitted.colour_error:.1f})")
    print(f"{project}: {k} theme{'s' if k != 1 else ''} ({names}); cell {grid.cell[0]} x "
          f"{grid.cell[1]} -> {gw + 1} x {gh + 1} vertices for the {w} x {h} photo; "
          f"label agreement {result.agreement:.1%}; {colour}; {cost.area_bytes:,} bytes per "
          f"area ({cost.area_bytes / max(1, w * h) * 8:.3f} bits/pixel) + "
          f"{cost.theme_bytes:,} of themes")
    _print_written(written)
    return 0


def _check_georeference(photo: str) -> None:
    """Refuse, before any work, a photo whose georeference no export could use (a zero or
    non-finite pixel size, corners beyond floating point): the project would carry it."""
    from terratheme.core.exchange.layout import world_frame
    from terratheme.core.io.georef import read_georeference
    from terratheme.core.io.images import image_info

    info, georeference = image_info(photo), read_georeference(photo)
    try:
        world_frame(georeference, (info.width, info.height), owner="photo")
    except TerrathemeError as exc:
        raise TerrathemeError(f"{photo}: {exc}") from None


def _style(args: argparse.Namespace) -> tuple:
    """The colour-map and boundary options of ``--colour-map``, ``--budget`` and
    ``--boundary``."""
    from terratheme.core.convert.colour_fit import ColourMapOptions
    from terratheme.core.render.boundary import BoundaryOptions

    if args.colour_map == "off":
        colour = None
    elif args.colour_map == "auto":
        colour = ColourMapOptions() if args.budget is None else ColourMapOptions(
            budget=args.budget)
    else:
        colour = ColourMapOptions(target=args.colour_map)
    return colour, BoundaryOptions() if args.boundary == "shaped" else None


def _print_written(written) -> None:
    for key, path in written.items():
        if key != "project":
            print(f"  {key}: {path}")


def _read_legend(args: argparse.Namespace, themes) -> dict[int, str] | None:
    """The class names of ``--legend``, checked against the other options before any work."""
    if not args.legend:
        return None
    from terratheme.core.io.legend import read_legend

    if not (args.scribbles or args.model):
        raise TerrathemeError("--legend names the classes of --scribbles or --model; "
                              "unsupervised themes are named by their looks")
    if themes != "auto":
        raise TerrathemeError("--legend names the themes cut from the photo: it does not go "
                              "with --themes names")
    return read_legend(args.legend)


def _load_model(name: str, legend: dict[int, str] | None):
    """A saved or shipped classifier; a legend renames its classes."""
    from terratheme.core.classify import load_model

    model = load_model(name)
    if legend:
        model.name_classes(legend)
    return model


def _run_tiled(args, project, preview, packed, themes, legend) -> int:
    """The bounded-memory path: tile by tile with a saved classifier or unsupervised."""
    from terratheme.core.convert.photo import write_outputs
    from terratheme.core.convert.tiled import convert_file_tiled
    from terratheme.core.errors import TerrathemeError

    if args.scribbles:
        raise TerrathemeError("--tile does not take --scribbles: train a model with "
                              "terratheme classify --model-out and give --model M, or omit "
                              "both for unsupervised themes")
    if args.tile < 16:
        raise TerrathemeError(f"--tile: N must be >= 16, not {args.tile}")
    if args.curve:
        raise TerrathemeError("--curve charts the cell choice over the whole photo; --tile "
                              "makes no such chart: drop one of them")
    if args.model and isinstance(themes, int):
        raise TerrathemeError("--themes K is for unsupervised classification; with --model "
                              "the classes are given (use auto or 1=name,2=name)")
    # Without --model: unsupervised themes fitted on windows spread over the photo.
    model = _load_model(args.model, legend) if args.model else None
    names = None if isinstance(themes, str | int) else themes
    k = themes if isinstance(themes, int) else "auto"
    colour, boundary = _style(args)
    with _scheduler(args) as scheduler, _tile_progress(args.photo, not args.model) as progress:
        proj = convert_file_tiled(args.photo, model, args.cell, names=names, themes=k,
                                  tile=args.tile, target_agreement=args.target_agreement,
                                  progress=progress, class_target=args.class_target,
                                  colour_map=colour, boundary=boundary, scheduler=scheduler,
                                  keep_specks=args.specks == "keep")
        written = write_outputs(proj, project, preview_path=preview, packed_path=packed)
    gh, gw = proj.grid.cells_shape
    k = len(proj.library)
    where = (f" on {args.scheduler}" if args.scheduler else
             f" on {args.workers} local workers" if args.workers else "")
    print(f"{project}: {k} theme{'s' if k != 1 else ''} ({', '.join(proj.library.names)}); cell "
          f"{proj.grid.cell[0]} -> {gw + 1} x {gh + 1} vertices, tile by tile ({args.tile} px)"
          f"{where}")
    _print_written(written)
    return 0


@contextlib.contextmanager
def _scheduler(args):
    """Where the tiles run: this process, a running cluster (--scheduler) or a local one."""
    from terratheme.core.io.cluster import TlsFiles, connect, local_cluster
    from terratheme.core.io.tiles import Scheduler

    if not (args.scheduler or args.workers):
        yield Scheduler.SERIAL
        return
    tls = None
    if args.tls_ca_file or args.tls_cert or args.tls_key:
        if not (args.tls_ca_file and args.tls_cert):
            raise TerrathemeError("--scheduler tls://: give --tls-ca-file and --tls-cert "
                                  "(and --tls-key unless the key is in the certificate)")
        tls = TlsFiles(args.tls_ca_file, args.tls_cert, args.tls_key)
    # The cluster is reached (or started) before any tile is read.
    client = connect(args.scheduler, tls=tls) if args.scheduler else local_cluster(args.workers)
    try:
        yield client
    finally:
        client.close()


@contextlib.contextmanager
def _tile_progress(photo: str, sampled: bool):
    """A progress bar of tiles done and megapixels per second, one stage after the other.

    ``sampled``: unsupervised, a first pass draws the samples of the themes.
    """
    import time

    from terratheme.app.progress import StageBar
    from terratheme.core.io.images import image_info

    info = image_info(photo)
    pixels = info.width * info.height
    stages = iter(["sample"] * sampled + ["classify", "colour map"])
    start = [time.perf_counter()]
    with StageBar(total=1, desc="convert (tiled)", unit="tile") as bar:

        def progress(done: int, total: int) -> None:
            bar.total, bar.n = total, done
            if done == 0:
                # A stage begins (run_tiles says (0, total) first): its clock starts.
                bar.set_description(next(stages, "tiles"))
                start[0] = time.perf_counter()
                bar.refresh()
                return
            seconds = max(time.perf_counter() - start[0], 1e-9)
            bar.set_postfix_str(f"{pixels * done / total / 1e6 / seconds:.1f} Mpx/s")

        yield progress
