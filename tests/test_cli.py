"""The CLI shell: every subcommand listed, errors one line with a non-zero status."""

import subprocess
import sys

import pytest

from app.cli import build_parser, main

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
        "import sys\nfrom app.cli import build_parser\nbuild_parser()\n"
        "print([m for m in sys.modules if m.startswith('PySide6')])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
