"""Outputs that survive faults and signals: no half-written file, sets all or none to a reader.

Processes are really signalled (SIGTERM, SIGINT, SIGKILL) in subprocesses;
a kill between the writes or between the renames of a file set is made by
patching ``os.replace`` in the child. Nothing found in a folder is ever
read, repaired or removed (a planted journal of the old design must do nothing).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import signal
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.io import atomic
from terratheme.core.io.atomic import atomic_path, file_set, write_bytes_atomic

REPO = Path(__file__).resolve().parents[1]
DEAD_PID = 999_999_999  # above any pid_max: no such process
#: what core.io.atomic names its temporaries
TEMPORARY_NAME = re.compile(r"^\.(?P<name>.+)\.tt-[0-9a-f]{12}\.tmp(?P<suffix>\.[A-Za-z0-9]+)?$")


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


def test_a_temporary_is_made_beside_the_target_and_renamed_onto_it(tmp_path):
    with atomic_path(tmp_path / "out.png") as tmp:
        match = TEMPORARY_NAME.match(tmp.name)
        assert tmp.parent == tmp_path and match and match["suffix"] == ".png"
        assert match["name"] == "out.png" and tmp.exists()
        tmp.write_bytes(b"1")
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]
    assert (tmp_path / "out.png").read_bytes() == b"1" and not atomic._LIVE


def test_a_failed_write_removes_the_temporary_and_keeps_the_old_file(tmp_path):
    (tmp_path / "out.bin").write_bytes(b"old")
    with pytest.raises(RuntimeError, match="disk full"), atomic_path(tmp_path / "out.bin") as t:
        t.write_bytes(b"half")
        raise RuntimeError("disk full")
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]
    assert (tmp_path / "out.bin").read_bytes() == b"old"


def test_a_late_write_error_at_fsync_keeps_the_old_file(tmp_path, monkeypatch):
    (tmp_path / "out.bin").write_bytes(b"old")

    def enospc(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic.os, "fsync", enospc)
    with pytest.raises(TerrathemeError, match="No space left"):
        write_bytes_atomic(tmp_path / "out.bin", b"new")
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]
    assert (tmp_path / "out.bin").read_bytes() == b"old"


def test_core_installs_no_signal_handler(tmp_path):
    done = _child(f"""
        import signal
        from terratheme.core.io.atomic import atomic_path, file_set
        with atomic_path({str(tmp_path / "a.bin")!r}) as tmp:
            tmp.write_bytes(b"x")
        with file_set([{str(tmp_path / "b.bin")!r}]) as files:
            files.temporary({str(tmp_path / "b.bin")!r}).write_bytes(b"x")
        print(all(signal.getsignal(s) is signal.SIG_DFL
                  for s in (signal.SIGTERM, signal.SIGHUP)))
        """)
    assert done.stdout.strip() == "True", done.stderr


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_the_cli_s_sigterm_handler_removes_the_temporary_and_terminates(tmp_path, signum):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    done = _child(f"""
        import signal, time
        from terratheme.app.cli import _on_terminate
        from terratheme.core.io.atomic import atomic_path
        signal.signal({int(signum)}, _on_terminate)
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


@pytest.mark.parametrize("kind", ["file", "set"])
def test_after_ctrl_c_a_swallowed_interrupt_commits_nothing(tmp_path, kind):
    """imagecodecs' input check, under tifffile's zlib tiles, can swallow the
    KeyboardInterrupt a Ctrl-C raises: the run went on and replaced the old render (the
    tiled render's interrupt test failed 1 run in about 80 on a loaded machine)."""
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    done = _child(f"""
        import os, signal, time
        from terratheme.app.cli import _on_interrupt
        from terratheme.core.io.atomic import atomic_path, file_set
        signal.signal(signal.SIGINT, _on_interrupt)

        def swallowed():
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(5)
            except KeyboardInterrupt:
                pass  # as a library may

        if {kind!r} == "file":
            with atomic_path({str(target)!r}) as tmp:
                tmp.write_bytes(b"new")
                swallowed()
        else:
            with file_set([{str(target)!r}]) as files:
                files.temporary({str(target)!r}).write_bytes(b"new")
                swallowed()
        print("committed")
        """)
    assert done.returncode == -signal.SIGINT and "committed" not in done.stdout, done.stderr
    assert "KeyboardInterrupt" in done.stderr
    assert target.read_bytes() == b"old" and _hidden(tmp_path) == []


def test_the_cli_refuses_commits_after_ctrl_c_except_in_the_editor():
    done = _child("""
        import signal
        from terratheme.app import cli
        cli.install_interrupt_handler("app")
        print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)
        cli.install_interrupt_handler("render")
        print(signal.getsignal(signal.SIGINT) is cli._on_interrupt)
        """)
    assert done.stdout.split() == ["True", "True"], done.stderr


def test_without_the_cli_s_handler_commits_go_on(tmp_path):
    """Only the console script's Ctrl-C refuses commits: core installs no policy."""
    done = _child(f"""
        import signal
        from terratheme.core.io.atomic import write_bytes_atomic
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            pass
        write_bytes_atomic({str(tmp_path / "out.bin")!r}, b"new")
        print("committed")
        """)
    assert done.returncode == 0 and "committed" in done.stdout, done.stderr
    assert (tmp_path / "out.bin").read_bytes() == b"new"


def test_a_sigkill_leftover_is_left_alone_and_the_next_write_needs_nothing_of_it(tmp_path):
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
    write_bytes_atomic(tmp_path / "out.bin", b"1")
    assert (tmp_path / "out.bin").read_bytes() == b"1" and _hidden(tmp_path) == left


def _old_journal(folder: Path, victim: str, backup: bytes | None) -> None:
    """What the old design's next run 'undid': a journal of a dead process naming ``victim``."""
    host = hashlib.sha1(socket.gethostname().encode()).hexdigest()[:8]
    stem = f"~tt{host}-{DEAD_PID}-0123456789ab"
    entry = {"final": victim, "temp": f".{victim}{stem}.tmp",
             "backup": None if backup is None else f".{victim}{stem}.bak",
             "inode": os.stat(folder / victim).st_ino}
    if backup is not None:
        (folder / entry["backup"]).write_bytes(backup)
    (folder / f".x{stem}.set").write_text(json.dumps({"entries": [entry]}))


@pytest.mark.parametrize("backup", [None, b"the attacker's content"])
def test_a_planted_journal_changes_no_file(tmp_path, backup):
    # Issue 33: the first write into a folder 'undid' any journal of a dead process: a
    # planted one deleted the file it named, or replaced it by the planted backup.
    (tmp_path / "victim.txt").write_bytes(b"mine")
    _old_journal(tmp_path, "victim.txt", backup)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    write_bytes_atomic(tmp_path / "render.png", b"new")
    with file_set([tmp_path / "a.bin", tmp_path / "b.bin"]) as files:
        for name in ("a.bin", "b.bin"):
            files.temporary(tmp_path / name).write_bytes(b"1")
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert after == {**before, "render.png": b"new", "a.bin": b"1", "b.bin": b"1"}


def test_a_scratch_file_is_always_removed(tmp_path):
    with atomic_path(tmp_path / "out.tif", suffix=".tif", rename=False) as part:
        assert TEMPORARY_NAME.match(part.name)["suffix"] == ".tif" and part.exists()
        part.write_bytes(b"level 0")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(RuntimeError, match="boom"), atomic_path(tmp_path / "out.tif",
                                                               rename=False):
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_just_after_the_temporary_is_made_leaves_nothing(tmp_path, monkeypatch):
    # Found by the render --tiled campaign: a Ctrl-C between creating the temporary
    # and entering the try block left it behind.
    real = atomic.os.close

    def close_then_interrupted(fd):
        real(fd)
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic.os, "close", close_then_interrupted)
    with pytest.raises(KeyboardInterrupt), atomic_path(tmp_path / "out.bin") as tmp:
        tmp.write_bytes(b"never")
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == [] and not atomic._LIVE


# -- file sets ------------------------------------------------------------------

def _old_set(folder: Path) -> list[Path]:
    paths = [folder / "s.ttpack", folder / "s_preview.png", folder / "s.ttproj"]
    for p in paths[1:]:
        p.write_bytes(b"old " + p.name.encode())
    return paths  # s.ttpack has no old version


def _contents(paths: list[Path]) -> list[bytes | None]:
    return [p.read_bytes() if p.exists() else None for p in paths]


def _write_all(files, paths) -> None:
    for p in paths:
        files.temporary(p).write_bytes(b"new " + p.name.encode())


def test_a_set_renames_its_members_then_the_project_last(tmp_path, monkeypatch):
    paths = _old_set(tmp_path)
    order = []
    real_replace, real_unlink = os.replace, os.unlink
    monkeypatch.setattr(atomic.os, "replace", lambda a, b: (order.append(Path(b).name),
                                                           real_replace(a, b)))
    monkeypatch.setattr(atomic.os, "unlink", lambda a: (order.append("rm " + Path(a).name),
                                                        real_unlink(a)))
    with file_set(paths) as files:
        assert [files.temporary(p).suffix for p in paths] == [".ttpack", ".png", ".ttproj"]
        _write_all(files, paths)
        assert _contents(paths)[1:] == [b"old s_preview.png", b"old s.ttproj"]
    # The old project goes first: from then on no set is there until the new one is whole.
    assert order == ["rm s.ttproj", "s.ttpack", "s_preview.png", "s.ttproj"]
    assert _contents(paths) == [b"new " + p.name.encode() for p in paths]
    assert _hidden(tmp_path) == [] and not atomic._LIVE


def test_a_failure_while_writing_leaves_the_old_set(tmp_path):
    paths = _old_set(tmp_path)
    before = _contents(paths)
    with pytest.raises(RuntimeError, match="disk full"), file_set(paths) as files:
        files.temporary(paths[0]).write_bytes(b"new")
        raise RuntimeError("disk full")
    assert _contents(paths) == before and _hidden(tmp_path) == []


def test_a_failed_rename_leaves_no_project_to_trust(tmp_path, monkeypatch):
    paths = _old_set(tmp_path)
    real, calls = os.replace, []

    def flaky(a, b):
        calls.append(b)
        if len(calls) == 2:
            raise PermissionError(13, "Permission denied", str(b))
        real(a, b)

    monkeypatch.setattr(atomic.os, "replace", flaky)
    with pytest.raises(PermissionError), file_set(paths) as files:
        _write_all(files, paths)
    assert not paths[-1].exists() and _hidden(tmp_path) == []


def test_members_in_other_folders_and_files_not_written(tmp_path):
    (tmp_path / "sub").mkdir()
    paths = [tmp_path / "sub" / "a.png", tmp_path / "b.png", tmp_path / "m.json"]
    paths[1].write_bytes(b"old b")
    with file_set(paths) as files:
        files.temporary(paths[0]).write_bytes(b"a")
        files.temporary(paths[2]).write_bytes(b"m")
    assert _contents(paths) == [b"a", b"old b", b"m"]
    with pytest.raises(TerrathemeError, match="not written"), file_set(paths) as files:
        files.temporary(paths[0]).write_bytes(b"a2")
    assert _contents(paths) == [b"a", b"old b", b"m"]


def test_writers_inside_a_set_write_to_its_temporaries(tmp_path):
    paths = _old_set(tmp_path)
    before = _contents(paths)
    with file_set(paths):
        for p in paths:
            write_bytes_atomic(p, b"new " + p.name.encode())
        assert _contents(paths) == before  # nothing renamed before the set is whole
    assert _contents(paths) == [b"new " + p.name.encode() for p in paths]
    assert _hidden(tmp_path) == []


def test_set_arguments_are_checked(tmp_path):
    with pytest.raises(TerrathemeError, match="same file twice"), file_set(
            [tmp_path / "a", tmp_path / "a"]):
        pass
    with pytest.raises(TerrathemeError, match="does not exist"), file_set(
            [tmp_path / "none" / "a"]) as files:
        files.temporary(tmp_path / "none" / "a")
    with pytest.raises(TerrathemeError, match="no files|at least one"), file_set([]):
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
    with atomic.file_set(paths) as files:
        for p in paths:
            files.temporary(p).write_bytes(b"new " + p.name.encode())
            if {die_between_writes} and p == paths[0]:
                os.kill(os.getpid(), signal.SIGKILL)
"""


@pytest.mark.parametrize("where", ["between writes", "between renames"])
def test_a_set_killed_midway_is_never_a_mixed_set(tmp_path, where):
    paths = _old_set(tmp_path)
    before = _contents(paths)
    done = _child(_SET_CHILD.format(paths=[str(p) for p in paths],
                                    die_between_writes=where == "between writes",
                                    die_after_renames=where == "between renames"))
    assert done.returncode == -signal.SIGKILL, done.stderr
    if where == "between writes":
        assert _contents(paths) == before  # the old set, whole
    else:
        # A new member is in place, so there is no project: nothing names a mixed set.
        assert _contents(paths)[0] == b"new s.ttpack" and not paths[-1].exists()
    assert all(TEMPORARY_NAME.match(n) for n in _hidden(tmp_path))
    # The next run of the same outputs makes a whole set without touching the leftovers.
    left = _hidden(tmp_path)
    with file_set(paths) as files:
        _write_all(files, paths)
    assert _contents(paths) == [b"new " + p.name.encode() for p in paths]
    assert _hidden(tmp_path) == left


def test_concurrent_sets_to_one_folder_end_whole(tmp_path):
    # Each commit holds a lock on the folder: the last set committed is the one there.
    paths = [tmp_path / "a.bin", tmp_path / "b.bin", tmp_path / "m.json"]
    code = textwrap.dedent(f"""
        import os
        from terratheme.core.io.atomic import file_set
        paths = {[str(p) for p in paths]!r}
        for k in range(30):
            with file_set(paths) as files:
                for p in paths:
                    files.temporary(p).write_bytes(b"%d %d" % (os.getpid(), k))
        """)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    procs = [subprocess.Popen([sys.executable, "-c", code], cwd=REPO, env=env) for _ in range(6)]
    seen = 0
    while any(p.poll() is None for p in procs):
        # A reader: the members it read belong to the manifest that was there before and after.
        try:
            # The manifest's inode and change time: an inode freed by one commit can be
            # reused by the next, so the inode alone does not tell two manifests apart.
            first = os.stat(paths[2])
            a, b, m = _contents(paths)
            last = os.stat(paths[2])
            if (last.st_ino, last.st_ctime_ns) != (first.st_ino, first.st_ctime_ns):
                continue
        except FileNotFoundError:
            continue
        assert a == b == m, (a, b, m)
        seen += 1
    assert [p.wait(timeout=120) for p in procs] == [0] * 6 and seen
    contents = _contents(paths)
    assert contents[0] == contents[1] == contents[2] and _hidden(tmp_path) == []


def test_a_full_disk_while_writing_names_the_output_not_its_temporary(tmp_path):
    # A writer's OSError often names no file (zipfile) or the temporary: the output is named.
    with pytest.raises(OSError) as err, atomic_path(tmp_path / "out.bin"):
        raise OSError(28, "No space left on device")
    assert err.value.filename == str(tmp_path / "out.bin")
    with pytest.raises(OSError) as err, file_set([tmp_path / "a.bin", tmp_path / "b.bin"]) as fs:
        # A writer that makes its own temporary of the set's (as save_project does).
        with atomic_path(fs.temporary(tmp_path / "b.bin")) as inner:
            raise OSError(28, "No space left on device", str(inner))
    assert err.value.filename == str(tmp_path / "b.bin")
    # Another file's error keeps its own name, and a read error naming none stays unnamed.
    with pytest.raises(OSError) as err, atomic_path(tmp_path / "out.bin"):
        raise OSError(2, "No such file or directory", "/elsewhere/input.png")
    assert err.value.filename == "/elsewhere/input.png"
    with pytest.raises(OSError) as err, atomic_path(tmp_path / "out.bin"):
        raise OSError(5, "Input/output error")
    assert err.value.filename is None
    assert list(tmp_path.iterdir()) == []


def test_a_pipe_or_a_device_is_never_replaced_by_an_output(tmp_path):
    from terratheme.app.outputs import check_outputs

    fifo = tmp_path / "preview.png"
    os.mkfifo(fifo)
    with pytest.raises(TerrathemeError, match="preview.png: is a pipe, not a file to write"):
        write_bytes_atomic(fifo, b"png")
    with pytest.raises(TerrathemeError, match="preview.png: is a pipe, not an output file"):
        check_outputs([fifo])
    with pytest.raises(TerrathemeError, match=f"{os.devnull}: is a device, not an output file"):
        check_outputs([os.devnull])
    assert fifo.is_fifo() and [p.name for p in tmp_path.iterdir()] == ["preview.png"]
    # A link to a device is the link replaced, never the device.
    link = tmp_path / "link.png"
    link.symlink_to(os.devnull)
    assert check_outputs([link]) == [link]
