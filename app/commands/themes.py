"""``terratheme themes``: the shipped themes, by the names ``new --themes`` and ``convert`` take."""

from __future__ import annotations

import argparse

NAME = "themes"
HELP = "list the shipped themes: the name to use, texture file, display colour, size"
ORDER = 15


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``terratheme themes``."""
    parser.add_argument("--json", action="store_true", help="print one JSON list")


def run(args: argparse.Namespace) -> int:
    """Print one line per shipped theme (or JSON with ``--json``)."""
    import json
    from pathlib import Path

    from terratheme.core.themes.library import SHIPPED_THEMES_DIR, shipped_theme_library

    rows = []
    for index, theme in enumerate(shipped_theme_library()):
        h, w = theme.texture.shape[:2]
        rows.append({"index": index, "name": theme.name, "file": Path(theme.source).name,
                     "colour": list(theme.colour), "width": w, "height": h})
    if args.json:
        print(json.dumps(rows))
        return 0
    for r in rows:
        red, green, blue = r["colour"]
        r["shown"] = f"#{red:02x}{green:02x}{blue:02x} ({red},{green},{blue})"
    widths = [max(len(title), *(len(r[key]) for r in rows))
              for key, title in (("name", "name"), ("file", "file"), ("shown", "colour"))]
    print(f"{'name':<{widths[0]}}  {'file':<{widths[1]}}  {'colour':<{widths[2]}}  size")
    for r in rows:
        print(f"{r['name']:<{widths[0]}}  {r['file']:<{widths[1]}}  {r['shown']:<{widths[2]}}  "
              f"{r['width']} x {r['height']}")
    print(f"{len(rows)} themes in {SHIPPED_THEMES_DIR}; name them as shown, e.g. "
          f"--themes {','.join(r['name'] for r in rows[:2])} (quote names with spaces)")
    return 0
