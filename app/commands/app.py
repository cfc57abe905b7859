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


#: window sides ``--size`` accepts (the screenshot is a pixmap of the whole window)
MIN_SIDE, MAX_SIDE = 200, 8192


def run(args: argparse.Namespace) -> int:
    from terratheme.app.outputs import check_outputs
    from terratheme.core.errors import TerrathemeError

    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError as exc:
        raise TerrathemeError(f"--size must look like 1400x860, got {args.size!r}") from exc
    if not (MIN_SIDE <= w <= MAX_SIDE and MIN_SIDE <= h <= MAX_SIDE):
        raise TerrathemeError(f"--size {w}x{h}: each side must be {MIN_SIDE}..{MAX_SIDE} pixels")
    # The screenshot's path is checked before Qt starts (and its folder made).
    check_outputs([args.screenshot], inputs=[args.target])
    if args.screenshot is not None:
        _check_screenshot_format(args.screenshot)
    from terratheme.app.editor.launch import run_editor

    return run_editor(args.target, screenshot=args.screenshot,
                      classify=not args.no_classify, size=(w, h))


def _check_screenshot_format(path: str) -> None:
    """Refuse, before the window is laid out, a screenshot name no Qt image writer takes."""
    from pathlib import Path

    from PySide6.QtGui import QImageWriter
    from terratheme.core.errors import TerrathemeError

    suffix = Path(path).suffix.lower().lstrip(".")
    known = sorted(bytes(f).decode() for f in QImageWriter.supportedImageFormats())
    if suffix not in known:
        what = f"no image format is written as '.{suffix}'" if suffix else "has no extension"
        raise TerrathemeError(f"{path}: {what}; name the screenshot .png, .jpg, ... "
                              f"({', '.join(known)})")
