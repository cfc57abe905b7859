"""The CLI shell: every subcommand listed, errors one line with a non-zero status."""

import subprocess
import sys

import numpy as np
import pytest
from terratheme.app.cli import build_parser, main
from terratheme.core.io.images import write_image

EXPECTED = {"new", "render", "classify", "convert", "pack", "unpack", "info", "perspective", "app",
            "export", "themes"}


def test_help_lists_every_subcommand(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    listed = {name for name in EXPECTED if f"    {name} " in out or f"    {name}\n" in out}
    assert listed == EXPECTED


def test_every_subcommand_has_its_own_help():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert set(sub.choices) >= EXPECTED
    for name, p in sub.choices.items():
        assert p.description, name


def test_no_subcommand_prints_help_and_fails(capsys):
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().out


def test_user_error_is_one_line_and_exit_2(tmp_path, capsys):
    status = main(["info", str(tmp_path / "missing.tpk")])
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1 and err.startswith("terratheme info: error:")
    assert "Traceback" not in err


def test_help_does_not_import_qt():
    code = (
        "import sys\nfrom terratheme.app.cli import build_parser\nbuild_parser()\n"
        "print([m for m in sys.modules if m.startswith('PySide6')])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize(("argv", "value", "parsed"), [
    (["export", "p.ttproj", "out", "--engine", "unity", "--size"], "640X360", (640, 360)),
    (["perspective", "in.png", "out.png", "--size"], "64x36", (64, 36)),
    (["new", "map.png", "p.ttproj", "--themes", "water", "--cell"], "16", (16, 16)),
    (["new", "map.png", "p.ttproj", "--themes", "water", "--cell"], "8x4", (8, 4)),
    (["render", "p.ttproj", "out.png", "--region"], "1,2,30,40", (1, 2, 30, 40)),
])
def test_integer_tuples_parse(argv, value, parsed):
    args = build_parser().parse_args([*argv, value])
    assert parsed in vars(args).values()


@pytest.mark.parametrize(("argv", "message"), [
    (["export", "p.ttproj", "out", "--engine", "unity", "--size", "64"],
     "argument --size: size must be WxH (integers), got '64'"),
    (["perspective", "in.png", "out.png", "--size", "64x36x2"],
     "argument --size: size must be WxH, e.g. 640x360, got '64x36x2'"),
    (["new", "map.png", "p.ttproj", "--themes", "water", "--cell", "8x4x2"],
     "argument --cell: cell must be N or NxM, got '8x4x2'"),
    (["new", "map.png", "p.ttproj", "--themes", "water", "--cell", "eight"],
     "argument --cell: cell must be N or NxM, got 'eight'"),
    (["render", "p.ttproj", "out.png", "--region", "1,2,3"],
     "argument --region: region must be x,y,w,h (integers), got '1,2,3'"),
])
def test_bad_integer_tuples_are_one_line_and_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert capsys.readouterr().err == f"terratheme {argv[0]}: error: {message}\n"


@pytest.mark.parametrize(("argv", "message"), [
    (["render", "p.ttproj", "out.png", "--bogus"], "terratheme: error: unrecognized arguments"),
    (["export", "p.ttproj", "out", "--engine", "doom"],
     "terratheme export: error: argument --engine: invalid choice: 'doom'"),
    (["nosuchcommand"], "terratheme: error: argument COMMAND: invalid choice"),
])
def test_argparse_errors_are_one_line(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and err.startswith(message), err


def _limited(mib: int):
    import resource

    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (mib << 20, resource.getrlimit(
            resource.RLIMIT_AS)[1]))
    return apply


@pytest.mark.skipif(sys.platform == "win32", reason="no address-space limit on Windows")
def test_below_the_address_space_a_command_needs_is_one_line(tmp_path):
    # Issue 33: under ulimit -v 300 MiB .. 1 GiB valid inputs ended in SIGSEGV, bad_alloc
    # aborts, ImportError tracebacks or a spurious exit 130.
    from terratheme.app.cli import MIN_ADDRESS_SPACE_MIB

    index = tmp_path / "map.png"
    write_image(index, np.zeros((4, 4, 1), np.uint8))
    argv = ["new", str(index), str(tmp_path / "p.ttproj"), "--themes", "water"]
    limit = MIN_ADDRESS_SPACE_MIB.get("new", 0) // 2 or 300
    proc = subprocess.run([sys.executable, "-m", "terratheme.app.cli", *argv],
                          capture_output=True, text=True, timeout=120,
                          preexec_fn=_limited(limit))
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.count("\n") == 1 and "ulimit -v" in proc.stderr, proc.stderr
    assert not (tmp_path / "p.ttproj").exists()


@pytest.mark.parametrize(("message", "name", "want"), [
    ("libfoo.so: failed to map segment from shared object", "foo",
     "cannot load foo (libfoo.so: failed to map segment from shared object)\n"),
    # The editor is an extra of the wheel: its absence says how to install it.
    ("No module named 'PySide6'", "PySide6",
     "cannot load PySide6 (No module named 'PySide6'); the editor is the 'app' extra: "
     "pip install 'terratheme[app]'\n"),
])
def test_a_library_that_cannot_load_is_one_line(monkeypatch, capsys, message, name, want):
    import terratheme.app.commands.themes

    def fail(args):
        raise ImportError(message, name=name)

    monkeypatch.setattr(terratheme.app.commands.themes, "run", fail)
    assert main(["themes"]) == 2
    assert capsys.readouterr().err == "terratheme themes: error: " + want
