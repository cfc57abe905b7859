"""Tile jobs on a dask.distributed cluster of worker processes: the serial result, bit for bit.

A ``LocalCluster`` of 2 worker processes is started here (the workers import
terratheme and read the photo from its path, as on a real cluster). The
quick tests share one cluster; the slow ones compare a whole conversion and
kill a worker half way.
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest
from distributed import Future
from terratheme.core.convert.colour_fit import ColourMapOptions
from terratheme.core.convert.photo import CODEC_SUFFIX
from terratheme.core.convert.region_sample import fit_unsupervised_region
from terratheme.core.convert.tile_vote import PredictLabels
from terratheme.core.convert.tiled import convert_file_tiled, grid_from_file
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.cluster import check_workers, connect, local_cluster, map_ordered, warm_up
from terratheme.core.io.images import read_image, write_image
from terratheme.core.io.tiles import Scheduler, run_tiles
from terratheme.core.packing import pack

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAMPLE = os.path.join(REPO, "sample_maps", "dubai_marina.jpg")


def brightest(pixels: np.ndarray) -> np.ndarray:
    """A per-pixel classifier (module level: workers import it by name): brightest channel."""
    return np.argmax(pixels[..., :3], axis=2).astype(np.uint8) + 1


def refuse_right_half(win, pixels: np.ndarray) -> int:
    """A tile job that fails, as a damaged tile would, right of column 64."""
    if win.x >= 64:
        raise TerrathemeError(f"tile at {win.x}: refused")
    return int(pixels.sum())


def per_process_fingerprint() -> tuple[str, str]:
    """Stands for another terratheme on every other process."""
    return str(os.getpid()), f"/elsewhere/{os.getpid()}/core"


def sum_with_part(win, pixels: np.ndarray, part: int) -> int:
    """A tile job with a per-tile part (``run_tiles(parts=...)``)."""
    return int(pixels.astype(np.int64).sum()) * 1000 + part


def mark_warm() -> None:
    """A warm-up call: leaves a mark in the worker process."""
    os.environ["TERRATHEME_TEST_WARMED"] = "1"


def warm_mark() -> str | None:
    return os.environ.get("TERRATHEME_TEST_WARMED")


def slow_mark() -> None:
    """A warm-up call that takes a while, then leaves its mark."""
    import time

    time.sleep(1.0)
    os.environ["TERRATHEME_TEST_SLOW_WARMED"] = "1"


def slow_mark_seen(item: int, shared: int) -> str | None:
    return os.environ.get("TERRATHEME_TEST_SLOW_WARMED")


def square(item: int, shared: int) -> int:
    return item * item + shared


def square_or_fail(item: int, shared: int) -> int:
    """Fails on item 17 (inside a task of several items)."""
    return square(item, shared) // (item - 17)


def _photo(path, h=160, w=224, seed=3):
    rng = np.random.default_rng(seed)
    coarse = rng.integers(0, 256, (h // 16 + 1, w // 16 + 1, 3), dtype=np.uint8)
    img = np.kron(coarse, np.ones((16, 16, 1), np.uint8))[:h, :w]
    img = np.clip(img.astype(int) + rng.integers(-30, 30, img.shape), 0, 255).astype(np.uint8)
    write_image(path, img, **({"tile": 32} if str(path).endswith(".tif") else {}))
    return img


@pytest.fixture(scope="module")
def cluster():
    with local_cluster(2) as client:
        yield client


def _same_project(a, b) -> None:
    assert np.array_equal(a.grid.indices, b.grid.indices)
    assert a.grid.cell == b.grid.cell
    assert a.library.names == b.library.names
    for ta, tb in zip(a.library.textures, b.library.textures, strict=True):
        assert np.array_equal(ta, tb)
    assert (a.colour_map is None) == (b.colour_map is None)
    if a.colour_map is not None:
        assert a.colour_map.data == b.colour_map.data
        assert np.array_equal(a.colour_map.pixels, b.colour_map.pixels)
    assert pack(a.grid.indices, curve="auto").to_bytes() == \
        pack(b.grid.indices, curve="auto").to_bytes()


@pytest.mark.parametrize("name", ["photo.tif", "photo.png"])
def test_cluster_grid_equals_serial_grid(tmp_path, cluster, name):
    # A tiled TIFF is read by the workers; a PNG (no random access) here, its tiles sent.
    path = tmp_path / name
    _photo(path)
    serial = grid_from_file(path, (8, 6), brightest, tile=48, overlap=5)
    seen = []
    on_cluster = grid_from_file(path, (8, 6), brightest, tile=48, overlap=5, scheduler=cluster,
                                progress=lambda d, t: seen.append((d, t)))
    assert np.array_equal(on_cluster.indices, serial.indices)
    # Both workers took tiles; progress runs 0..total in order.
    total = seen[-1][1]
    assert [d for d, _ in seen] == list(range(total + 1)) and total > 4
    assert len(cluster.nthreads()) == 2


@pytest.mark.slow
@pytest.mark.parametrize("name", ["photo.tif", "photo.png"])
def test_cluster_conversion_equals_serial(tmp_path, cluster, name):
    path = tmp_path / name
    write_image(path, read_image(SAMPLE)[:320, :384, :3],
                **({"tile": 64} if name.endswith(".tif") else {}))
    serial = convert_file_tiled(path, None, 16, tile=128)
    on_cluster = convert_file_tiled(path, None, 16, tile=128, scheduler=cluster)
    assert serial.colour_map is not None
    _same_project(serial, on_cluster)


def test_results_reach_the_sink_in_order_with_few_in_flight(cluster):
    # Warming the workers up queues one import task each, ahead of the run.
    warm_up(cluster, ["terratheme.core.convert.tiled"])
    got = []
    n = map_ordered(cluster, square, list(range(23)), 5, lambda i, r: got.append((i, r)),
                    in_flight=3)
    assert n == 23 and got == [(i, i * i + 5) for i in range(23)]


def slow_square(item: int, shared: int) -> int:
    time.sleep(0.2)
    return square(item, shared)


def test_tasks_the_cluster_cancels_are_resubmitted_and_keep_the_order(cluster):
    # As when a worker dies with the scattered shared data: the run's futures are cancelled.
    got, cancelled = [], []

    def cancel_once(done: int, total: int) -> None:
        if done == 3 and not cancelled:
            keys = list(cluster.futures)
            cluster.cancel([Future(k, cluster) for k in keys], force=True)
            cancelled.append(len(keys))

    n = map_ordered(cluster, slow_square, list(range(12)), 0,
                    lambda i, r: got.append((i, r)), in_flight=4, group=1,
                    progress=cancel_once)
    assert cancelled and cancelled[0] > 1
    assert n == 12 and got == [(i, i * i) for i in range(12)]


def test_tasks_of_several_items_keep_the_order_and_shrink_to_one_at_the_end(cluster,
                                                                          monkeypatch):
    from terratheme.core.io.cluster import MAX_GROUP, group_size

    submits = []
    real = cluster.submit

    def counting(func, *args, **kw):
        submits.append(len(args[1]))
        return real(func, *args, **kw)

    monkeypatch.setattr(cluster, "submit", counting)
    got = []
    n = map_ordered(cluster, square, list(range(101)), 2, lambda i, r: got.append((i, r)))
    assert n == 101 and got == [(i, i * i + 2) for i in range(101)]
    # Several items a task while many remain, one each at the end.
    assert sum(submits) == 101 and len(submits) < 101 // 2
    assert max(submits) <= MAX_GROUP and submits[-4:] == [1, 1, 1, 1]
    assert submits == sorted(submits, reverse=True)
    submits.clear()
    map_ordered(cluster, square, list(range(9)), 0, lambda i, r: None, group=1)
    assert submits == [1] * 9
    assert group_size(10_000, 4) == MAX_GROUP and group_size(7, 4) == 1


def test_a_failing_item_inside_a_group_fails_the_run(cluster):
    with pytest.raises(ZeroDivisionError):
        map_ordered(cluster, square_or_fail, list(range(40)), 0, lambda i, r: None)


def test_colour_map_tiles_are_encoded_on_the_workers(cluster, monkeypatch):
    import terratheme.core.model.colour_map as colour_map_module
    from terratheme.core.convert.colour_fit import ClusterTiles
    from terratheme.core.model.colour_map import ColourMap

    rng = np.random.default_rng(5)
    gains = rng.integers(90, 170, (50, 70, 3), dtype=np.uint8)
    limits = dict(colour_map_module.ONE_IMAGE_LIMITS, jpegxl=(40, 1200))
    monkeypatch.setattr(colour_map_module, "ONE_IMAGE_LIMITS", limits)
    monkeypatch.setattr(colour_map_module, "MAP_TILE", 16)
    serial = ColourMap.encode(gains, 8, "jpegxl", 95)

    def not_here(*args, **kw):
        raise AssertionError("the client encoded a tile")

    # The client encodes nothing: its codec fails (the workers' is their own).
    monkeypatch.setattr(colour_map_module, "encode_image", not_here)
    on_cluster = ColourMap.encode(gains, 8, "jpegxl", 95, run=ClusterTiles(cluster))
    assert len(serial.tiles) == 4 * 5
    assert on_cluster.tiles == serial.tiles and on_cluster.tile == serial.tile
    assert np.array_equal(on_cluster.pixels, serial.pixels)


def test_warm_up_runs_its_calls_on_every_worker(cluster):
    from terratheme.core.convert.tiled import WarmKernels
    from terratheme.core.render.boundary import BoundaryOptions
    from terratheme.core.render.renderer import RenderOptions

    # The tile jobs' kernels on tiny inputs, as convert_file_tiled sends them, then a mark.
    warm = WarmKernels(brightest, RenderOptions(threads=1, boundary=BoundaryOptions()))
    warm_up(cluster, ["terratheme.core.convert.tiled"], [warm, mark_warm])
    # The warm-up tasks are pinned one per worker and nobody waits: poll for the marks.
    import time

    for _ in range(200):
        if set(cluster.run(warm_mark).values()) == {"1"}:
            break
        time.sleep(0.1)
    assert list(cluster.run(warm_mark).values()) == ["1", "1"]


def test_tasks_start_after_the_warm_up(cluster, monkeypatch):
    from terratheme.core.io import cluster as cluster_module

    # A task's function unpickled on a worker while the warm-up imported the same package
    # on another thread could see it half initialised (ImportError, seen in CI): the
    # first task is submitted only once every warm-up task has finished.
    warm_up(cluster, [], [slow_mark])
    warming = list(cluster_module._WARMING[cluster])
    submit, done_at_submit = cluster.submit, []

    def watched(*args, **kw):
        done_at_submit.append(all(f.done() for f in warming))
        return submit(*args, **kw)

    monkeypatch.setattr(cluster, "submit", watched)
    seen = []
    map_ordered(cluster, slow_mark_seen, list(range(8)), 0, lambda i, r: seen.append(r))
    assert done_at_submit and all(done_at_submit)
    assert seen == ["1"] * len(seen) and len(seen) == 8


def test_per_tile_parts_reach_their_tiles_on_every_scheduler(tmp_path, cluster):
    path = tmp_path / "p.png"
    _photo(path, 100, 140)
    got = {}
    for name, where in [("serial", Scheduler.SERIAL), ("cluster", cluster)]:
        out = []
        run_tiles(path, sum_with_part, lambda w, r, out=out: out.append((w.x, w.y, r)), tile=48,
                  scheduler=where, parts=lambda w: w.x + 7 * w.y)
        got[name] = out
    assert got["serial"] == got["cluster"]
    assert [r % 1000 for _, _, r in got["serial"]] == [x + 7 * y for x, y, _ in got["serial"]]


def _worker_settings() -> tuple:
    import dask

    return (dask.config.get("distributed.worker.profile.enabled"),
            dask.config.get("distributed.admin.tick.interval"),
            os.environ.get("MALLOC_TRIM_THRESHOLD_"),
            dask.config.get("distributed.worker.memory.monitor-interval"),
            dask.config.get("distributed.admin.system-monitor.interval"))


def test_local_workers_run_without_the_profiler_and_reuse_memory(cluster):
    # The statistical profiler feeds only the dashboard (off): each worker has it off, and
    # glibc's adaptive reuse of freed arrays is left on (no forced trim threshold).
    settings = cluster.run(_worker_settings)
    assert len(settings) == 2
    assert set(settings.values()) == {(False, "1s", None, "1s", "2s")}


def test_a_failing_tile_fails_the_run_in_one_line(tmp_path, cluster):
    path = tmp_path / "photo.png"
    _photo(path, 96, 128)
    with pytest.raises(TerrathemeError, match="tile at 64: refused"):
        run_tiles(path, refuse_right_half, lambda w, r: None, tile=64, scheduler=cluster)


def test_a_file_the_workers_cannot_read_is_refused_first(tmp_path, cluster):
    with pytest.raises(TerrathemeError, match=r"cannot read it \(2 of 2 workers\).*file system"):
        check_workers(cluster, str(tmp_path / "elsewhere.tif"))


def test_workers_running_other_code_are_refused_first(tmp_path, cluster, monkeypatch):
    import terratheme.core.io.cluster as cl

    path = tmp_path / "photo.png"
    _photo(path, 64, 64)
    monkeypatch.setattr(cl, "code_fingerprint", per_process_fingerprint)
    with pytest.raises(TerrathemeError, match=r"runs another terratheme \(core at /elsewhere/"
                                              r".*2 of 2 workers\): install"):
        convert_file_tiled(path, None, 8, tile=32, scheduler=cluster)


def test_connect_errors_are_one_line():
    from distributed import LocalCluster

    with pytest.raises(TerrathemeError, match="cannot reach the dask scheduler at tcp://"):
        connect("tcp://127.0.0.1:1", timeout=2)
    with LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as empty:
        with pytest.raises(TerrathemeError, match="has no worker"):
            connect(empty.scheduler_address, timeout=0.5)
    with pytest.raises(TerrathemeError, match="at least 1 worker"):
        local_cluster(0)


@pytest.mark.slow
def test_killing_a_worker_mid_run_gives_the_same_result(tmp_path):
    path = tmp_path / "photo.tif"
    write_image(path, read_image(SAMPLE)[..., :3], tile=64)
    model = fit_unsupervised_region(path)
    classify = PredictLabels(model)
    overlap = model.context_pixels
    serial = grid_from_file(path, 16, classify, tile=160, overlap=overlap)
    with local_cluster(2) as client:
        pids = client.run(os.getpid)
        victim = sorted(pids.values())[0]
        killed = []

        def kill_once(done: int, total: int) -> None:
            # Two tiles in, one worker dies with its tiles in flight.
            if done == 2 and not killed:
                os.kill(victim, signal.SIGKILL)
                killed.append(total)

        on_cluster = grid_from_file(path, 16, classify, tile=160, overlap=overlap,
                                    scheduler=client, progress=kill_once)
        assert killed and killed[0] > 8
        assert victim not in client.run(os.getpid).values()
    assert np.array_equal(on_cluster.indices, serial.indices)


@pytest.mark.slow
def test_cli_on_local_workers_writes_the_serial_outputs(tmp_path):
    from terratheme.app.cli import main

    path = tmp_path / "photo.tif"
    write_image(path, read_image(SAMPLE)[..., :3], tile=64)
    assert main(["convert", str(path), str(tmp_path / "s.ttproj"), "--tile", "256"]) == 0
    assert main(["convert", str(path), str(tmp_path / "w.ttproj"), "--tile", "256",
                 "--workers", "2"]) == 0
    # The colour map file is in the default codec's format (JPEG XL today).
    colour = f"_colour{CODEC_SUFFIX[ColourMapOptions().codec]}"
    for suffix in (".ttpack", colour, "_preview.png"):
        assert (tmp_path / f"s{suffix}").is_file()
        assert (tmp_path / f"s{suffix}").read_bytes() == (tmp_path / f"w{suffix}").read_bytes()
    from terratheme.core.model.project import load_project

    _same_project(load_project(tmp_path / "s.ttproj"), load_project(tmp_path / "w.ttproj"))


def test_cli_refuses_cluster_options_without_tiles(tmp_path, capsys):
    from terratheme.app.cli import main

    path = tmp_path / "photo.png"
    _photo(path, 64, 64)
    out = str(tmp_path / "o.ttproj")
    assert main(["convert", str(path), out, "--workers", "2"]) == 2
    assert "give --tile N" in capsys.readouterr().err
    assert main(["convert", str(path), out, "--tile", "32", "--workers", "2",
                 "--scheduler", "tcp://127.0.0.1:1"]) == 2
    assert "pick one" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["convert", str(path), out, "--tile", "32", "--workers", "0"])
    assert exc.value.code == 2 and "--workers must be in [1, 1024]" in capsys.readouterr().err
    assert not (tmp_path / "o.ttproj").exists()


def test_a_passed_check_is_not_run_again_for_the_same_workers_and_path(tmp_path, cluster,
                                                                       monkeypatch):
    import terratheme.core.io.cluster as cl

    seen, other = tmp_path / "a.png", tmp_path / "b.png"
    _photo(seen, 32, 32)
    _photo(other, 32, 32)
    check_workers(cluster, str(seen))
    # The same workers and path: passed before, not asked again; a new path is checked.
    monkeypatch.setattr(cl, "code_fingerprint", per_process_fingerprint)
    check_workers(cluster, str(seen))
    with pytest.raises(TerrathemeError, match="runs another terratheme"):
        check_workers(cluster, str(other))
