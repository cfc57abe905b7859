"""The ``terratheme`` command line: ``main(argv=None) -> int``.

Subcommands are discovered from :mod:`app.commands`. Errors the user can fix
(bad or hostile input, a missing folder, a full disk, not enough memory)
exit with status 2 and one line on stderr naming the problem, never a
traceback; Ctrl-C exits with 130.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import pkgutil
import signal
import sys
from collections.abc import Sequence

import terratheme.app.commands
from terratheme.app.outputs import folders_made_for_outputs
from terratheme.core import __version__
from terratheme.core.errors import OptionError, TerrathemeError


def _command_modules() -> list:
    mods = [
        importlib.import_module(f"terratheme.app.commands.{info.name}")
        for info in pkgutil.iter_modules(terratheme.app.commands.__path__)
        if not info.name.startswith("_")
    ]
    return sorted(mods, key=lambda m: (getattr(m, "ORDER", 100), m.NAME))


class _Parser(argparse.ArgumentParser):
    """argparse with its errors as one line (``terratheme CMD: error: ...``), not the usage."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {_one_line(message)}\n")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every subcommand."""
    parser = _Parser(
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


#: least address space (``ulimit -v``, MiB) each command starts and runs a small input in,
#: measured on a 2-core machine (docs/decisions.md); below it native libraries end the
#: process (SIGSEGV, std::bad_alloc) or fail to load, so the CLI says so first
MIN_ADDRESS_SPACE_MIB = {"unpack": 768, "themes": 1024, "convert": 1408, "app": 1664}
#: for the commands not listed
DEFAULT_ADDRESS_SPACE_MIB = 1280


def address_space_shortfall(command: str) -> str:
    """Why ``command`` cannot run under this process's address-space limit, or ""."""
    try:
        import resource
    except ImportError:  # pragma: no cover - no address-space limits (Windows)
        return ""
    soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    need = MIN_ADDRESS_SPACE_MIB.get(command, DEFAULT_ADDRESS_SPACE_MIB) << 20
    if soft == resource.RLIM_INFINITY or soft >= need:
        return ""
    return (f"the address-space limit (ulimit -v) is {soft >> 20} MiB, below the "
            f"{need >> 20} MiB this command needs; raise it (ulimit -v {need >> 10})")


def cv2_error() -> type[BaseException]:
    """OpenCV's exception class if OpenCV is loaded already, else one nothing raises."""
    cv2 = sys.modules.get("cv2")
    return getattr(cv2, "error", None) or _NeverRaised


class _NeverRaised(Exception):
    pass


def out_of_memory(exc: BaseException) -> bool:
    """An exception that means memory ran out: a thread that cannot start (its stack cannot
    be mapped) or a native library's std::bad_alloc (OpenCV's cv2.error)."""
    text = str(exc)
    return ("can't start new thread" in text or "bad_alloc" in text
            or "Insufficient memory" in text or "Failed to allocate" in text)


def _one_line(text: str) -> str:
    """A message as one line (readers' messages may quote multi-line library errors), its
    control characters escaped (a file name holding ESC [2J must not clear the terminal)."""
    line = "; ".join(part.strip() for part in str(text).splitlines() if part.strip())
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in line)


def flag_of(field: str) -> str:
    """The CLI flag of an options field (``reduce_palette`` -> ``--reduce-palette``)."""
    return "--" + field.replace("_", "-")


def _error_text(exc: TerrathemeError) -> str:
    """The library's message, options spelled as this CLI's flags."""
    return exc.spelled(flag_of) if isinstance(exc, OptionError) else str(exc)


def _os_error(exc: OSError) -> str:
    where = exc.filename if exc.filename is not None else ""
    why = exc.strerror or str(exc)
    return f"{where}: {why}" if where else why


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the process exit status.

    A problem with the input or the environment (library, OS, memory, address-space or
    loading errors) is one line on stderr and status 2; Ctrl-C one line and 130.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_run", None) is None:
        parser.print_help()
        return 2
    name = f"terratheme {args.command}"
    # Mesa's EGL loader prints warnings of its own; a command's problem is one line.
    os.environ.setdefault("EGL_LOG_LEVEL", "fatal")
    shortfall = address_space_shortfall(args.command)
    if shortfall:
        print(f"{name}: error: {shortfall}", file=sys.stderr)
        return 2
    try:
        with folders_made_for_outputs() as made:
            status = int(args._run(args) or 0)
            if status:
                made.remove_empty()
            return status
    except TerrathemeError as exc:
        print(f"{name}: error: {_one_line(_error_text(exc))}", file=sys.stderr)
    except ImportError as exc:
        # A library that cannot be mapped (out of memory) or is missing from the install.
        extra = ("; the editor is the 'app' extra: pip install 'terratheme[app]'"
                 if (exc.name or "").startswith("PySide6") else "")
        print(f"{name}: error: cannot load {exc.name or 'a library'} "
              f"({_one_line(str(exc))[:160]}){extra}", file=sys.stderr)
    except (MemoryError, RuntimeError, cv2_error()) as exc:
        if not isinstance(exc, MemoryError) and not out_of_memory(exc):
            raise
        # Commands with a bounded-memory path say so when it was not taken.
        hint = " (--tile N works in bounded memory)" if getattr(args, "tile", 0) is None else ""
        print(f"{name}: error: not enough memory for this input{hint}", file=sys.stderr)
    except BrokenPipeError:
        # The reader of our output went away: say nothing more on stdout.
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except OSError as exc:
        print(f"{name}: error: {_one_line(_os_error(exc))}", file=sys.stderr)
    except KeyboardInterrupt:
        print(f"{name}: interrupted", file=sys.stderr)
        return 130
    return 2


def _on_terminate(signum: int, frame: object) -> None:
    """SIGTERM/SIGHUP: remove this process's temporary files, then die of the signal."""
    atomic = sys.modules.get("terratheme.core.io.atomic")
    if atomic is not None:
        atomic.remove_temporaries()
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)


def _on_interrupt(signum: int, frame: object) -> None:
    """Ctrl-C: Python's KeyboardInterrupt, and no output committed after it even if a
    library swallows that exception (:func:`core.io.atomic.refuse_commits`)."""
    atomic = sys.modules.get("terratheme.core.io.atomic")
    if atomic is not None:
        atomic.refuse_commits()
    raise KeyboardInterrupt


def install_interrupt_handler(command: str | None) -> None:
    """:func:`_on_interrupt` for Ctrl-C (when Python's own handler is set), except for the
    editor (``app``): it goes on after a Ctrl-C and saves what its user asks for."""
    if command != "app" and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_interrupt)


def console_main() -> None:
    """The ``terratheme`` console script: :func:`main`, then exit with its status.

    SIGTERM and SIGHUP (when not ignored) remove this process's temporary files first.
    After Ctrl-C no output is committed (:func:`install_interrupt_handler`) and the
    process ends at once (the temporaries are gone already), so a pool thread interrupted
    while starting cannot hold the interpreter's exit.
    """
    for signum in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(signum) is signal.SIG_DFL:
            signal.signal(signum, _on_terminate)
    install_interrupt_handler(sys.argv[1] if len(sys.argv) > 1 else None)
    code = main()
    if code == 130:
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(130)
    sys.exit(code)


if __name__ == "__main__":
    console_main()
