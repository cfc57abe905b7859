"""``terratheme app``: the editor window."""

from __future__ import annotations

import argparse

NAME = "app"
HELP = "open the editor window (a project, or a new project over a photo)"
ORDER = 90


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", nargs="?", metavar="PROJECT|PHOTO",
                        help="a .ttproj project, or a photo to start a new project over "
                        "(default: the bundled sample, else an empty project)")
    parser.add_argument("--screenshot", metavar="FILE",
                        help="lay out and render the window to FILE (PNG), then exit "
                        "(works with QT_QPA_PLATFORM=offscreen)")
    parser.add_argument("--no-classify", action="store_true",
                        help="with a photo, do not classify it: the grid starts all one "
                        "theme (the shipped themes are in the palette)")
    parser.add_argument("--size", default="1400x860", metavar="WxH",
                        help="window size (default 1400x860)")


def run(args: argparse.Namespace) -> int:
    from core.errors import TerrathemeError

    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError as exc:
        raise TerrathemeError(f"--size must look like 1400x860, got {args.size!r}") from exc
    from app.editor.launch import run_editor

    return run_editor(args.target, screenshot=args.screenshot,
                      classify=not args.no_classify, size=(w, h))
