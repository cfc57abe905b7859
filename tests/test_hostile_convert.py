"""``convert --tile`` (with ``--workers``/``--scheduler``) and ``--model`` on hostile input.

Through the real CLI: a damaged photo on the tiled path, a scheduler address
that cannot work, a damaged model file: status 2, one line naming the
problem, and no project, preview or packed layer left behind.
"""

from __future__ import annotations

import contextlib

import numpy as np
import pytest
from hostile_fuzz import check_refused, hidden_files, run_cli
from terratheme.core.classify import SupervisedOptions, train_classifier
from terratheme.core.io.images import write_image


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    """A 600 x 600 photo as PNG, TIFF and JPEG, and each cut in half."""
    folder = tmp_path_factory.mktemp("photos")
    img = np.random.default_rng(0).integers(0, 255, (600, 600, 3)).astype(np.uint8)
    for suffix in (".png", ".tif", ".jpg"):
        write_image(folder / f"photo{suffix}", img)
        data = (folder / f"photo{suffix}").read_bytes()
        (folder / f"cut{suffix}").write_bytes(data[:len(data) // 2])
    return folder


def _nothing_written(folder) -> None:
    assert list(folder.iterdir()) == [] and not hidden_files(folder)


@pytest.mark.parametrize(("name", "why"), [
    ("cut.tif", "damaged or truncated image"),
    # found: libjpeg fills the rows it lacks with grey, and a window took them (exit 0)
    ("cut.jpg", "damaged or truncated image"),
    # a PNG's chunks are checked before libpng reads it
    pytest.param("cut.png", "truncated PNG", marks=pytest.mark.slow)])
def test_a_damaged_photo_on_the_tiled_path_is_one_line(photos, tmp_path, name, why):
    proc = run_cli("convert", photos / name, tmp_path / "p.ttproj", "--tile", "256")
    check_refused(proc, f"{name}: {why}")
    _nothing_written(tmp_path)


@pytest.mark.slow
def test_a_damaged_photo_on_local_workers_is_one_line(photos, tmp_path):
    proc = run_cli("convert", photos / "cut.tif", tmp_path / "p.ttproj", "--tile", "256",
                   "--workers", "1")
    check_refused(proc, "cut.tif: damaged or truncated image")
    _nothing_written(tmp_path)


@pytest.mark.parametrize(("address", "why"), [
    ("nonsense", "missing port number"),
    pytest.param("http://127.0.0.1:80", "unknown address scheme 'http'",
                 marks=pytest.mark.slow),
])
def test_a_scheduler_address_that_cannot_work_is_one_line(photos, tmp_path, address, why):
    proc = run_cli("convert", photos / "photo.png", tmp_path / "p.ttproj", "--tile", "256",
                   "--scheduler", address)
    check_refused(proc, f"cannot reach the dask scheduler at {address}", why)
    _nothing_written(tmp_path)


@pytest.fixture(scope="module")
def cut_model(tmp_path_factory):
    folder = tmp_path_factory.mktemp("model")
    photo = np.zeros((32, 48, 3), np.uint8)
    photo[:, 24:] = (200, 180, 120)
    mask = np.zeros((32, 48), np.uint8)
    mask[8, 2:20], mask[20, 28:46] = 1, 2
    train_classifier([(photo, mask)], SupervisedOptions(n_trees=2)).save(folder / "m.ttc")
    data = (folder / "m.ttc").read_bytes()
    (folder / "cut.ttc").write_bytes(data[:len(data) - 40])
    return folder / "cut.ttc"


@pytest.mark.parametrize("command", [pytest.param("convert", marks=pytest.mark.slow),
                                     "convert --tile 256", "classify"])
def test_a_damaged_model_is_one_line_before_any_output(photos, tmp_path, cut_model, command):
    name, *extra = command.split()
    out = ["-o", tmp_path / "l.png"] if name == "classify" else [tmp_path / "p.ttproj"]
    proc = run_cli(name, photos / "photo.png", *out, *extra, "--model", cut_model)
    check_refused(proc, "cut.ttc")
    _nothing_written(tmp_path)


@pytest.mark.slow
def test_a_busy_dashboard_port_prints_no_warning(capfd):
    # Found by this campaign: with port 8787 held (another cluster: another user's, or
    # another test's), --workers printed distributed's four-line warning before our line.
    import socket
    import warnings

    from terratheme.core.io.cluster import local_cluster

    holder = socket.socket()
    with contextlib.suppress(OSError):  # already held by someone else: just as busy
        holder.bind(("", 8787))
        holder.listen(1)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            local_cluster(1).close()
    finally:
        holder.close()
    assert not [w for w in caught if "already in use" in str(w.message)]
    assert "already in use" not in capfd.readouterr().err
