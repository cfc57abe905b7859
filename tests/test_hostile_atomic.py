"""Outputs that survive signals: no half-written file, no stray temporary, sets all or nothing.

Processes are really signalled (SIGTERM, SIGINT, SIGKILL) in subprocesses;
a kill between the writes or between the renames of a file set is made by
patching ``os.replace`` in the child to kill it after the first rename.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.io import atomic, temporaries
from terratheme.core.io.atomic import atomic_file_set, atomic_path, write_bytes_atomic
from terratheme.core.io.stale import clean_stale_temporaries
from terratheme.core.io.temporaries import HOST_TAG, TEMPORARY_NAME

REPO = Path(__file__).resolve().parents[1]
DEAD_PID = 999_999_999  # above any pid_max: no such process


def _default_signals() -> None:
    # A program started from a terminal: a suite run in the background or under nohup
    # ignores SIGINT and SIGHUP, and a child would inherit that (and rightly keep it).
    for signum in (signal.SIGINT, signal.SIGHUP):
        signal.signal(signum, signal.SIG_DFL)


def _child(code: str, *, wait_for: str | None = None, send: int | None = None
           ) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter; optionally signal it once it prints ``wait_for``."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], cwd=REPO, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_signals)
    if wait_for is not None:
        line = proc.stdout.readline()
        assert wait_for in line, line + proc.stderr.read()
        proc.send_signal(send)
    out, err = proc.communicate(timeout=60)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_temporaries_are_named_so_they_can_be_recognised(tmp_path):
    with atomic_path(tmp_path / "out.png") as tmp:
        match = TEMPORARY_NAME.match(tmp.name)
        assert match and match["kind"] == "tmp" and match["suffix"] == ".png"
        assert match["host"] == HOST_TAG and int(match["pid"]) == os.getpid()
        tmp.write_bytes(b"1")
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_removes_the_temporary_and_terminates(tmp_path, signum):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    done = _child(f"""
        import time
        from terratheme.core.io.atomic import atomic_path
        with atomic_path({str(target)!r}) as tmp:
            tmp.write_bytes(b"x" * 100_000)
            print("ready", flush=True)
            time.sleep(30)
        """, wait_for="ready", send=signum)
    assert done.returncode == -signum
    assert target.read_bytes() == b"old" and _hidden(tmp_path) == []


def test_ctrl_c_removes_the_temporary(tmp_path):
    target = tmp_path / "out.bin"
    done = _child(f"""
        import time
        from terratheme.core.io.atomic import atomic_path
        try:
            with atomic_path({str(target)!r}) as tmp:
                tmp.write_bytes(b"x")
                print("ready", flush=True)
                time.sleep(30)
        except KeyboardInterrupt:
            print("interrupted")
        """, wait_for="ready", send=signal.SIGINT)
    assert done.returncode == 0 and "interrupted" in done.stdout
    assert list(tmp_path.iterdir()) == []


def test_a_handler_of_the_program_s_own_is_left_alone(tmp_path):
    done = _child(f"""
        import signal, time
        from terratheme.core.io.atomic import atomic_path
        mine = lambda s, f: print("mine", flush=True)
        signal.signal(signal.SIGTERM, mine)
        with atomic_path({str(tmp_path / "o.bin")!r}) as tmp:
            tmp.write_bytes(b"x")
        print(signal.getsignal(signal.SIGTERM) is mine)
        """)
    assert done.stdout.strip() == "True"


def test_sigkill_leftovers_are_removed_by_the_next_write_in_the_folder(tmp_path):
    done = _child(f"""
        import os, signal
        from terratheme.core.io.atomic import atomic_path
        with atomic_path({str(tmp_path / "out.bin")!r}) as tmp:
            tmp.write_bytes(b"x" * 1000)
            os.kill(os.getpid(), signal.SIGKILL)
        """)
    assert done.returncode == -signal.SIGKILL
    left = _hidden(tmp_path)
    assert len(left) == 1 and TEMPORARY_NAME.match(left[0])
    # Things that look alike but must stay: ours (alive), another host's, a folder,
    # a symlink, other hidden files.
    keep = [f".out.bin~tt{HOST_TAG}-{os.getpid()}-0123456789ab.tmp.bin",
            f".out.bin~ttffffffff-{DEAD_PID}-0123456789ab.tmp",
            ".out.bin~ttnothex0-1-0123456789ab.tmp", ".bashrc", ".out.bin.tmp"]
    for name in keep:
        (tmp_path / name).write_bytes(b"keep")
    (tmp_path / f".dir~tt{HOST_TAG}-{DEAD_PID}-0123456789ab.tmp").mkdir()
    (tmp_path / f".link~tt{HOST_TAG}-{DEAD_PID}-0123456789ab.tmp").symlink_to(tmp_path / ".bashrc")
    write_bytes_atomic(tmp_path / "other.bin", b"1")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [*keep, "other.bin", f".dir~tt{HOST_TAG}-{DEAD_PID}-0123456789ab.tmp",
         f".link~tt{HOST_TAG}-{DEAD_PID}-0123456789ab.tmp"])


def test_clean_stale_temporaries_reports_what_it_removed(tmp_path):
    stale = tmp_path / f".a.png~tt{HOST_TAG}-{DEAD_PID}-0123456789ab.tmp.png"
    stale.write_bytes(b"x")
    assert clean_stale_temporaries(tmp_path) == [stale]
    assert clean_stale_temporaries(tmp_path) == []


# -- file sets ------------------------------------------------------------------

def _old_set(folder: Path) -> list[Path]:
    paths = [folder / "s.ttpack", folder / "s_preview.png", folder / "s.ttproj"]
    for p in paths[1:]:
        p.write_bytes(b"old " + p.name.encode())
    return paths  # s.ttpack has no old version


def _contents(paths: list[Path]) -> list[bytes | None]:
    return [p.read_bytes() if p.exists() else None for p in paths]


def test_a_set_is_renamed_in_order_with_the_project_last(tmp_path, monkeypatch):
    paths = _old_set(tmp_path)
    order = []
    real = os.replace
    monkeypatch.setattr(atomic.os, "replace", lambda a, b: (order.append(Path(b).name),
                                                           real(a, b)))
    with atomic_file_set(paths) as temps:
        assert [t.suffix for t in temps] == [".ttpack", ".png", ".ttproj"]
        for p, t in zip(paths, temps, strict=True):
            t.write_bytes(b"new " + p.name.encode())
    assert order == ["s.ttpack", "s_preview.png", "s.ttproj"]
    assert _contents(paths) == [b"new " + p.name.encode() for p in paths]
    assert _hidden(tmp_path) == []


def test_a_failure_while_writing_leaves_the_old_set(tmp_path):
    paths = _old_set(tmp_path)
    before = _contents(paths)
    with pytest.raises(RuntimeError, match="disk full"), atomic_file_set(paths) as temps:
        temps[0].write_bytes(b"new")
        raise RuntimeError("disk full")
    assert _contents(paths) == before and _hidden(tmp_path) == []


def test_a_failed_rename_rolls_the_set_back(tmp_path, monkeypatch):
    paths = _old_set(tmp_path)
    before = _contents(paths)
    real, calls = os.replace, []

    def flaky(a, b):
        calls.append(b)
        if len(calls) == 3:
            raise PermissionError(13, "Permission denied", str(b))
        real(a, b)

    monkeypatch.setattr(atomic.os, "replace", flaky)
    with pytest.raises(PermissionError), atomic_file_set(paths) as temps:
        for t in temps:
            t.write_bytes(b"new")
    assert _contents(paths) == before and _hidden(tmp_path) == []


def test_set_arguments_are_checked(tmp_path):
    with pytest.raises(TerrathemeError, match="share one folder"):
        (tmp_path / "sub").mkdir()
        with atomic_file_set([tmp_path / "a", tmp_path / "sub" / "b"]):
            pass
    with pytest.raises(TerrathemeError, match="same file twice"), atomic_file_set(
            [tmp_path / "a", tmp_path / "a"]):
        pass
    with pytest.raises(TerrathemeError, match="does not exist"), atomic_file_set(
            [tmp_path / "none" / "a"]):
        pass


_SET_CHILD = """
    import os, signal
    from pathlib import Path
    from terratheme.core.io import atomic
    paths = [Path(p) for p in {paths!r}]
    real = os.replace
    def replace_then_die(a, b):
        real(a, b)
        if {die_after_renames} and Path(b).name == paths[0].name:
            os.kill(os.getpid(), signal.SIGKILL)
    atomic.os.replace = replace_then_die
    with atomic.atomic_file_set(paths) as temps:
        for p, t in zip(paths, temps):
            t.write_bytes(b"new " + p.name.encode())
            if {die_between_writes} and t == temps[0]:
                os.kill(os.getpid(), signal.SIGKILL)
"""


@pytest.mark.parametrize("where", ["between writes", "between renames"])
def test_a_set_killed_midway_is_made_whole_by_the_next_run(tmp_path, where):
    paths = _old_set(tmp_path)
    before = _contents(paths)
    done = _child(_SET_CHILD.format(paths=[str(p) for p in paths],
                                    die_between_writes=where == "between writes",
                                    die_after_renames=where == "between renames"))
    assert done.returncode == -signal.SIGKILL, done.stderr
    if where == "between renames":
        # The new pack is in place beside the old project: an inconsistent set, and a journal.
        assert _contents(paths)[0] == b"new s.ttpack" and _contents(paths)[2] == before[2]
        assert any(name.endswith(".set") for name in _hidden(tmp_path))
    assert _hidden(tmp_path)
    touched = clean_stale_temporaries(tmp_path)
    assert touched and _contents(paths) == before and _hidden(tmp_path) == []


def test_sigterm_during_the_renames_waits_for_them(tmp_path):
    paths = _old_set(tmp_path)
    done = _child(f"""
        import os, signal
        from pathlib import Path
        from terratheme.core.io import atomic
        paths = [Path(p) for p in {[str(p) for p in paths]!r}]
        real = os.replace
        def replace_and_signal(a, b):
            real(a, b)
            if Path(b) == paths[0]:
                os.kill(os.getpid(), signal.SIGTERM)
        atomic.os.replace = replace_and_signal
        with atomic.atomic_file_set(paths) as temps:
            for p, t in zip(paths, temps):
                t.write_bytes(b"new " + p.name.encode())
        print("not reached")
        """)
    assert done.returncode == -signal.SIGTERM and "not reached" not in done.stdout
    assert _contents(paths) == [b"new " + p.name.encode() for p in paths]
    assert _hidden(tmp_path) == []


# -- temporaries for intermediate data, and Ctrl-C at the worst moment ----------

def test_a_scratch_file_is_a_recognised_temporary_and_always_removed(tmp_path):
    with atomic_path(tmp_path / "out.tif", suffix=".tif", rename=False) as part:
        match = TEMPORARY_NAME.match(part.name)
        assert match and match["suffix"] == ".tif" and part.exists()
        part.write_bytes(b"level 0")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(RuntimeError, match="boom"), atomic_path(tmp_path / "out.tif",
                                                               rename=False):
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_just_after_the_temporary_is_made_leaves_nothing(tmp_path, monkeypatch):
    # Found by the render --tiled campaign: a Ctrl-C between creating the temporary
    # and entering the try block left it behind.
    real = atomic._create

    def create_then_interrupted(path):
        real(path)
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic, "_create", create_then_interrupted)
    with pytest.raises(KeyboardInterrupt), atomic_path(tmp_path / "out.bin") as tmp:
        tmp.write_bytes(b"never")
    assert list(tmp_path.iterdir()) == [] and not temporaries._STATE.live
