"""The ``terratheme`` command line: ``main(argv=None) -> int``.

Subcommands are discovered from :mod:`app.commands`. Errors the user can fix
exit with status 2 and one line on stderr naming the problem.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence

import app.commands
from core import __version__
from core.errors import TerrathemeError


def _command_modules() -> list:
    mods = [
        importlib.import_module(f"app.commands.{info.name}")
        for info in pkgutil.iter_modules(app.commands.__path__)
        if not info.name.startswith("_")
    ]
    return sorted(mods, key=lambda m: (getattr(m, "ORDER", 100), m.NAME))


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="terratheme",
        description="Thematic terrain texture authoring: orthophotos to theme grids, "
        "rendering, editing, low-angle preview and space-filling-curve packing.",
    )
    parser.add_argument("--version", action="version", version=f"terratheme {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=mod.HELP)
        mod.configure(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_run", None) is None:
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except (TerrathemeError, OSError) as exc:
        print(f"terratheme {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"terratheme {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
