"""Tile jobs on a dask.distributed cluster: connect or start one, run tasks in order, bounded.

:func:`map_ordered` maps one pure function over tile windows: shared data is scattered
once, at most ``in_flight`` tasks are outstanding, results reach the sink in item order,
and a task lost with a dead worker is run again. Workers read the photo from its path and
must run the client's terratheme (:func:`check_workers`). :func:`local_cluster` starts
TLS-only workers with no HTTP port; :func:`connect` joins a running scheduler. Tasks run
numba and OpenCV on one thread: a worker thread is a core.
"""

from __future__ import annotations

import logging
import os
import warnings
import weakref
from collections.abc import Callable, Sequence
from concurrent.futures import CancelledError
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from terratheme.core.errors import TerrathemeError
from terratheme.core.io.inputs import check_input_file

if TYPE_CHECKING:
    from distributed import Client

#: seconds to wait for a scheduler to answer, and for its first worker
CONNECT_TIMEOUT = 20.0
#: tasks in flight per worker thread (one running, one queued behind it)
IN_FLIGHT_PER_THREAD = 2
#: most items one task runs (:func:`map_ordered`)
MAX_GROUP = 8
#: most tasks :func:`map_ordered` resubmits after the cluster cancelled them (lost workers)
MAX_RESUBMITS = 64
#: dask settings of a local cluster: no profiler or dashboard feeds, slower ticks and
#: monitors, and glibc's own memory reuse (dask's ``MALLOC_TRIM_THRESHOLD_`` makes every
#: array a fresh mmap); a tile job's memory is bounded by its tile (docs/decisions.md).
QUIET_LOCAL = {"distributed.worker.profile.enabled": False,
               "distributed.admin.tick.interval": "1s",
               "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
               "distributed.worker.memory.monitor-interval": "1s",
               "distributed.admin.system-monitor.interval": "2s",
               # No HTTP routes: the servers' ports are closed at start (:func:`local_cluster`)
               # and serve nothing before that.
               "distributed.scheduler.http.routes": [],
               "distributed.worker.http.routes": []}


def _one_thread(func: Callable[[Any, Any], Any], item: Any, shared: Any) -> Any:
    """Run one task with numba's and OpenCV's pools at one thread: a worker thread is a core."""
    import cv2
    import numba

    # numba's count is per calling thread; OpenCV's per process (one task per thread).
    numba.set_num_threads(1)
    cv2.setNumThreads(1)
    return func(item, shared)


def _run_group(func: Callable[[Any, Any], Any], group: list, shared: Any) -> list:
    """Consecutive items of :func:`map_ordered` in one task, each as :func:`_one_thread` runs it."""
    return [_one_thread(func, item, shared) for item in group]


def group_size(remaining: int, limit: int, most: int | None = None) -> int:
    """Items in the next task: ``remaining / (2 * limit)`` (guided self-scheduling), 1..``most``."""
    most = MAX_GROUP if most is None else int(most)
    return max(1, min(most, int(remaining) // (2 * max(1, int(limit)))))


@dataclass(frozen=True)
class TlsFiles:
    """The certificates of a ``tls://`` scheduler (dask's ``--tls-ca-file --tls-cert --tls-key``).

    ``ca_file`` checks the scheduler's certificate; ``cert`` is this client's (PEM, it may
    hold the key); ``key`` the private key when not in ``cert``.
    """

    ca_file: str
    cert: str
    key: str | None = None


def _close_http(dask_scheduler=None, dask_worker=None) -> None:
    """Stop a dask server's HTTP listener (dashboard, metrics): a port nobody asked for."""
    server = dask_scheduler if dask_scheduler is not None else dask_worker
    if getattr(server, "http_server", None) is not None:
        server.http_server.stop()


def local_cluster(workers: int, threads: int = 1) -> Client:
    """A client of a new local cluster of ``workers`` processes (closing it stops them).

    Everything listens on 127.0.0.1 over TLS with temporary credentials held only by this
    process and the workers, so no other local user can attach and run code as ours; HTTP
    ports are closed once started (a restarted worker's has no routes).
    """
    if int(workers) < 1 or int(threads) < 1:
        raise TerrathemeError(f"a local cluster needs at least 1 worker of 1 thread, got "
                              f"{workers} x {threads}")
    import dask
    from distributed import Client

    with warnings.catch_warnings(), dask.config.set(QUIET_LOCAL):
        # The scheduler's HTTP server falls back from port 8787 to a free one when another
        # cluster holds it, with a four-line warning on stderr; any free port will do.
        warnings.filterwarnings("ignore", message="Port .* is already in use",
                                module=r"distributed\.")
        # security=True: new temporary credentials, given to the cluster it starts (tls://).
        client = Client(n_workers=int(workers), threads_per_worker=int(threads),
                        processes=True, host="127.0.0.1", security=True,
                        dashboard_address=None, silence_logs=logging.CRITICAL)
    try:
        client.run_on_scheduler(_close_http)
        client.run(_close_http)
    except BaseException:
        client.close()
        raise
    return client


def _security(address: str, tls: TlsFiles | None):
    """The ``distributed.security.Security`` of a client of ``address``, checked in one line."""
    from distributed.security import Security

    scheme = address.split("://", 1)[0] if "://" in address else "tcp"
    if tls is not None and scheme != "tls":
        raise TerrathemeError(f"TLS certificates are for a tls:// scheduler, not {address}")
    if tls is None:
        # dask's own configuration (distributed.comm.tls.*), if any.
        security = Security()
    else:
        # OpenSSL opens the files with no check: a FIFO would block it for ever.
        for path in (tls.ca_file, tls.cert, tls.key):
            if path is not None:
                check_input_file(path, "a PEM certificate file")
        security = Security(tls_ca_file=str(tls.ca_file), tls_client_cert=str(tls.cert),
                            tls_client_key=None if tls.key is None else str(tls.key),
                            require_encryption=True)
    if scheme == "tls" and not (security.tls_ca_file and security.tls_client_cert):
        raise TerrathemeError(f"the scheduler at {address} speaks TLS: give its certificates "
                              "(--tls-ca-file, --tls-cert, --tls-key)")
    try:
        # The certificates are read here (an SSL context is made), so a bad file fails first.
        security.get_connection_args("client")
    except (OSError, ValueError) as exc:
        reason = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise TerrathemeError(f"TLS certificates for {address}: {reason}") from None
    return security


async def _handshake(address: str, security, timeout: float) -> None:
    """dask's connection handshake with ``address``, all of it within ``timeout`` seconds."""
    import asyncio

    from distributed.comm import connect as comm_connect

    async def shake() -> None:
        # dask's own retries end first (a refused port: its OSError), the handshake's
        # wait at ``timeout``.
        comm = await comm_connect(address, timeout=0.8 * timeout,
                                  **security.get_connection_args("client"))
        await comm.close()

    await asyncio.wait_for(shake(), timeout)


def connect(address: str, timeout: float | None = None,
            tls: TlsFiles | None = None) -> Client:
    """A client of the running dask scheduler at ``address`` (``tcp://`` or ``tls://host:port``).

    The handshake is tried first within ``timeout`` seconds (default :data:`CONNECT_TIMEOUT`;
    dask's own connect hangs on a port that never answers). TerrathemeError when the
    scheduler does not answer, is not dask, refuses the certificates, or has no worker.
    """
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    from distributed import Client

    timeout = CONNECT_TIMEOUT if timeout is None else float(timeout)
    security = _security(address, tls)
    try:
        # On a thread of its own: the caller's thread may already run an event loop.
        with ThreadPoolExecutor(1) as pool:
            pool.submit(asyncio.run, _handshake(address, security, timeout)).result()
    except TimeoutError:
        raise TerrathemeError(f"the dask scheduler at {address} does not answer (waited "
                              f"{timeout:g} s)") from None
    except (OSError, ValueError, TypeError) as exc:
        reason = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise TerrathemeError(f"cannot reach the dask scheduler at {address}: {reason}") from None
    except Exception:
        # Whatever else answered (an HTTP server, another protocol): read as a huge frame.
        raise TerrathemeError(f"{address} answers, but not as a dask scheduler") from None
    try:
        client = Client(address, timeout=timeout, security=security, set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        reason = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise TerrathemeError(f"cannot reach the dask scheduler at {address}: {reason}") from None
    try:
        client.wait_for_workers(1, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        client.close()
        raise TerrathemeError(f"the dask scheduler at {address} has no worker "
                              f"(waited {timeout:g} s)") from exc
    return client


def code_fingerprint() -> tuple[str, str]:
    """``(sha256 of every core/*.py, where core lives)``: which terratheme this process runs."""
    import hashlib
    from pathlib import Path

    import terratheme.core

    root = Path(terratheme.core.__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest(), str(root)


#: client -> the (workers, path) checks it passed (:func:`check_workers`)
_PASSED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def check_workers(client: Client, path: str) -> None:
    """Refuse, in one line, a cluster whose workers run another terratheme or cannot read ``path``.

    A check passed by the same worker addresses for the same path is not run again.
    """
    workers = frozenset(client.nthreads())
    passed = _PASSED.setdefault(client, set())
    if (workers, path) in passed:
        return
    ours, _ = code_fingerprint()
    try:
        theirs = client.run(code_fingerprint)
        seen = client.run(os.access, path, os.R_OK)
    except Exception as exc:
        # A worker without terratheme (or an older one) cannot even unpickle the check.
        reason = " ".join(str(exc).split())[:120]
        raise TerrathemeError(f"a dask worker cannot run terratheme ({reason}): install the "
                              "same terratheme on every worker") from None
    if not seen:
        raise TerrathemeError("the dask cluster has no worker")
    other = sorted((addr, where) for addr, (digest, where) in theirs.items() if digest != ours)
    if other:
        raise TerrathemeError(f"dask worker {other[0][0]} runs another terratheme (core at "
                              f"{other[0][1]}; {len(other)} of {len(theirs)} workers): install "
                              "the client's version on every worker")
    blind = sorted(addr for addr, ok in seen.items() if not ok)
    if blind:
        raise TerrathemeError(f"{path}: dask worker {blind[0]} cannot read it "
                              f"({len(blind)} of {len(seen)} workers): workers read the photo "
                              "from its path, so it must be on a file system they all see")
    if frozenset(seen) == workers:
        passed.add((workers, path))


def _import_all(modules: tuple[str, ...], calls: tuple[Callable[[], Any], ...]) -> None:
    import importlib

    for name in modules:
        importlib.import_module(name)
    for call in calls:
        call()


#: client -> its warm-up tasks not yet waited for (the next submission waits for them)
_WARMING: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def warm_up(client: Client, modules: Sequence[str],
            calls: Sequence[Callable[[], Any]] = ()) -> None:
    """Start importing ``modules`` and running ``calls`` (picklable, no arguments) on every
    worker, overlapping the client's serial work; :func:`map_ordered` waits for them (a
    module imported twice at once can be seen half initialised)."""
    # One task pinned to each worker (a task, not client.run: it must not block the
    # worker's event loop); the next map_ordered waits for them.
    _WARMING.setdefault(client, []).extend(
        client.submit(_import_all, tuple(modules), tuple(calls), workers=[address],
                      allow_other_workers=False, pure=False)
        for address in client.nthreads())


def _wait_for_warm_up(client: Client) -> None:
    """Wait for this client's warm-up tasks; a failed one is left to the real tasks to report."""
    from distributed import wait

    futures = _WARMING.pop(client, [])
    if futures:
        wait(futures)


def worker_threads(client: Client) -> int:
    """Worker threads of the cluster now (at least 1)."""
    return max(1, sum(client.nthreads().values()))


def _remote_error(exc: BaseException, what: str) -> BaseException:
    """A task's failure as the caller sees it: ours as they are, the rest in one line."""
    from distributed import KilledWorker

    if isinstance(exc, TerrathemeError):
        return exc
    if isinstance(exc, KilledWorker):
        return TerrathemeError(f"{what} killed every dask worker that ran it (out of memory? "
                               "try smaller tiles)")
    if isinstance(exc, ImportError):
        return TerrathemeError(f"a dask worker cannot run terratheme ({exc}): install the same "
                               "terratheme on every worker")
    return exc


def map_ordered(
    client: Client,
    func: Callable[[Any, Any], Any],
    items: Sequence[Any],
    shared: Any,
    sink: Callable[[Any, Any], None],
    *,
    in_flight: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    describe: Callable[[Any], str] = repr,
    payload: Callable[[Any], Any] | None = None,
    group: int | None = None,
) -> int:
    """Run ``func(item, shared)`` for every item on the cluster; ``sink(item, result)`` in order.

    ``func`` is module-level (workers import it by name); ``shared`` goes to every worker
    once. ``in_flight``: most tasks submitted and not yet sunk (default
    ``IN_FLIGHT_PER_THREAD`` per thread); ``describe(item)`` names an item in errors;
    ``payload(item)`` is made at submission and sent with the task, which then gets
    ``(item, payload(item))``; ``group``: items per task (default :func:`group_size`).
    Returns the number of items.
    """
    from distributed import as_completed

    total = len(items)
    if total == 0:
        return 0
    limit = max(1, int(in_flight) if in_flight else IN_FLIGHT_PER_THREAD * worker_threads(client))
    _wait_for_warm_up(client)
    # Everything the tasks share goes to every worker once.
    (shared_ref,) = client.scatter([shared], broadcast=True, hash=False)
    pending = as_completed()
    # task key -> (first item, items, batch, future); first item -> results of a finished task
    live: dict[str, tuple[int, int, list, Any]] = {}
    ready: dict[int, list] = {}
    submitted = sunk = resubmitted = 0

    def submit(first: int, batch: list) -> None:
        with warnings.catch_warnings():
            # A payload travels with its task on purpose (scattering moves the same bytes).
            warnings.filterwarnings("ignore", message="Sending large graph",
                                    module=r"distributed\.")
            fut = client.submit(_run_group, func, batch, shared_ref, pure=False)
        live[fut.key] = (first, len(batch), batch, fut)
        pending.add(fut)

    try:
        while sunk < total:
            # Keep ``limit`` tasks between submission and the sink.
            while submitted < total and len(live) + len(ready) < limit:
                size = int(group) if group else group_size(total - submitted, limit)
                batch = list(items[submitted:submitted + size])
                if payload is not None:
                    batch = [(item, payload(item)) for item in batch]
                submit(submitted, batch)
                submitted += len(batch)
            fut = next(pending)
            i, n, batch, _ = live.pop(fut.key)
            try:
                ready[i] = fut.result()
            except CancelledError:
                # A worker died with what the task needed (the scattered shared data, which
                # dask cannot recompute): scatter it again and resubmit the task, boundedly.
                resubmitted += 1
                if resubmitted > MAX_RESUBMITS:
                    raise TerrathemeError(f"tile {describe(items[i])}: the cluster lost its "
                                          f"tasks {MAX_RESUBMITS} times (workers dying?)") from None
                if shared_ref.status != "finished":
                    (shared_ref,) = client.scatter([shared], broadcast=True, hash=False)
                submit(i, batch)
                continue
            except Exception as exc:
                # Re-raised as the caller should see it (ours as they are, the rest named).
                what = describe(items[i]) + (f" or one of the {n - 1} after it" if n > 1 else "")
                raise _remote_error(exc, f"tile {what}") from None
            fut.release()
            # Results reach the sink in item order.
            while sunk in ready:
                for result in ready.pop(sunk):
                    sink(items[sunk], result)
                    sunk += 1
                    if progress is not None:
                        progress(sunk, total)
    finally:
        # Nothing of this run stays on the cluster, whatever stopped it.
        client.cancel([fut for *_, fut in live.values()] + [shared_ref])
    return total
