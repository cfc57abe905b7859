"""app.progress: a bar on a terminal, one line per stage in a log (no carriage returns)."""

from __future__ import annotations

import io
import re

import pytest
from terratheme.app.progress import StageBar, progress_bar


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_one_line_per_stage_and_no_bar():
    log = io.StringIO()
    with StageBar(total=4, desc="convert", file=log) as bar:
        for i in range(4):
            bar.n = i
            bar.refresh()
        bar.set_description("write")
        bar.set_description("write")  # the same stage: no line
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert len(lines) == 2
    assert re.fullmatch(r"convert: \d+\.\d s", lines[0])
    assert re.fullmatch(r"write: \d+\.\d s", lines[1])


def test_a_failed_stage_writes_nothing():
    log = io.StringIO()
    with pytest.raises(RuntimeError), StageBar(total=1, desc="render", file=log):
        raise RuntimeError("boom")
    assert log.getvalue() == ""


def test_a_terminal_gets_the_bar():
    term = Terminal()
    with progress_bar("render", 3, file=term) as progress:
        progress(1, 3)
        progress(3, 3)
    assert "\r" in term.getvalue() and "render" in term.getvalue()
    assert not re.search(r"render: \d+\.\d s\n", term.getvalue())


def test_progress_bar_in_a_log(capsys):
    with progress_bar("pack") as progress:
        progress(1, 1)
    err = capsys.readouterr().err
    assert re.fullmatch(r"pack: \d+\.\d s\n", err)
