"""Who can reach the tile jobs' cluster: credentials, no HTTP port, bounded connects.

A local cluster (``convert --workers``) takes only clients holding the
credentials made for it; a running scheduler (``--scheduler``) is reached over
``tls://`` with the user's certificates; a port that accepts and never answers,
or answers HTTP, is one line within the connect timeout.
"""

from __future__ import annotations

import os
import socket
import threading

import numpy as np
import psutil
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.cluster import TlsFiles, connect, local_cluster
from terratheme.core.io.images import write_image


def listening_ports(pid: int) -> set[int]:
    return {c.laddr.port for c in psutil.Process(pid).net_connections(kind="inet")
            if c.status == psutil.CONN_LISTEN}


def port_of(address: str) -> int:
    return int(address.rsplit(":", 1)[1])


@pytest.fixture(scope="module")
def cluster():
    with local_cluster(2) as client:
        yield client


def test_a_client_without_the_credentials_cannot_attach(cluster):
    import asyncio

    from distributed import Client
    from distributed.security import Security
    from terratheme.core.io.cluster import _handshake

    address = cluster.scheduler.address
    assert address.startswith("tls://127.0.0.1:")
    # The cluster's own credentials work.
    with Client(address, timeout=10, security=cluster.security, set_as_default=False) as ok:
        assert set(ok.run(os.getuid).values()) == {os.getuid()}
    plain = "tcp://" + address.split("://", 1)[1]
    # dask's handshake (a client's first step), bounded: a plain tcp:// client, a tls://
    # one without credentials and one with another cluster's credentials are refused.
    for where, security in [(plain, Security()), (address, Security()),
                            (address, Security.temporary())]:
        with pytest.raises((OSError, TypeError)):
            asyncio.run(_handshake(where, security, 10.0))
    asyncio.run(_handshake(address, cluster.security, 10.0))


def test_the_local_cluster_opens_no_http_port(cluster):
    # Workers listen on their TLS address only (no dashboard, no metrics).
    for address, pid in cluster.run(os.getpid).items():
        assert listening_ports(pid) == {port_of(address)}
    # The scheduler and the nannies (in this process) listen on their TLS addresses only.
    ours = {cluster.scheduler.address} | {n.address for n in cluster.cluster.workers.values()}
    assert listening_ports(os.getpid()) == {port_of(a) for a in ours}


class Server:
    """A TCP server on 127.0.0.1 that accepts and then sleeps, or answers HTTP."""

    def __init__(self, http: bool) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.http = http
        self.held: list[socket.socket] = []
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        threading.Thread(target=self.serve, daemon=True).start()

    def serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.held.append(conn)
            if self.http:
                conn.recv(65536)
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n"
                             b"Connection: close\r\n\r\n")
                conn.close()

    def close(self) -> None:
        self.sock.close()
        for conn in self.held:
            conn.close()


def connect_error(address: str, timeout: float) -> str:
    """The error ``connect`` gives, run on a thread so a hang fails the test instead."""
    found: list[BaseException] = []

    def run() -> None:
        try:
            connect(address, timeout=timeout).close()
        except BaseException as exc:  # handed to the test
            found.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(60 * timeout)
    assert not thread.is_alive(), "connect hung past its timeout"
    assert found and isinstance(found[0], TerrathemeError), found
    return str(found[0])


@pytest.mark.parametrize("http", [False, True], ids=["silent", "http"])
def test_a_port_that_is_no_scheduler_is_one_line(http):
    server = Server(http)
    try:
        message = connect_error(server.address, timeout=1.0)
    finally:
        server.close()
    expected = "answers, but not as a dask scheduler" if http else "does not answer"
    assert expected in message and "\n" not in message


def test_cli_a_silent_scheduler_exits_2_in_one_line(tmp_path, capsys, monkeypatch):
    import terratheme.core.io.cluster as cl
    from terratheme.app.cli import main

    monkeypatch.setattr(cl, "CONNECT_TIMEOUT", 1.0)
    photo = tmp_path / "p.png"
    write_image(photo, np.zeros((64, 64, 3), np.uint8))
    server = Server(False)
    try:
        code = main(["convert", str(photo), str(tmp_path / "o.ttproj"), "--tile", "32",
                     "--scheduler", server.address])
    finally:
        server.close()
    err = capsys.readouterr().err.strip()
    assert code == 2 and "does not answer (waited 1 s)" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "o.ttproj").exists()


def _credentials(folder) -> TlsFiles:
    """A self-signed certificate (its own CA) and its key, as PEM files."""
    from distributed.security import Security

    temp = Security.temporary()
    cert, key = folder / "cert.pem", folder / "key.pem"
    cert.write_text(temp.tls_ca_file)  # temporary() keeps the PEM text itself
    key.write_text(temp.tls_scheduler_key)
    return TlsFiles(str(cert), str(cert), str(key))


def test_a_tls_scheduler_takes_the_users_certificates(tmp_path):
    from distributed import LocalCluster
    from distributed.security import Security

    tls = _credentials(tmp_path)
    security = Security(tls_ca_file=tls.ca_file, tls_scheduler_cert=tls.cert,
                        tls_scheduler_key=tls.key, tls_worker_cert=tls.cert,
                        tls_worker_key=tls.key, tls_client_cert=tls.cert,
                        tls_client_key=tls.key, require_encryption=True)
    with LocalCluster(n_workers=1, processes=False, security=security, protocol="tls://",
                      host="127.0.0.1", dashboard_address=None) as running:
        address = running.scheduler_address
        with connect(address, timeout=10, tls=tls) as client:
            assert client.run(os.getuid)
        with pytest.raises(TerrathemeError, match="speaks TLS: give its certificates"):
            connect(address, timeout=2)
        with pytest.raises(TerrathemeError, match="are for a tls:// scheduler"):
            connect("tcp://" + address.split("://", 1)[1], timeout=2, tls=tls)
    bad = tmp_path / "bad.pem"
    bad.write_text("not a certificate")
    with pytest.raises(TerrathemeError, match="TLS certificates for tls://"):
        connect("tls://127.0.0.1:1", timeout=1, tls=TlsFiles(str(bad), str(bad)))


def test_cli_tls_options_need_a_scheduler(tmp_path, capsys):
    from terratheme.app.cli import main

    photo = tmp_path / "p.png"
    write_image(photo, np.zeros((64, 64, 3), np.uint8))
    tls = _credentials(tmp_path)
    out = str(tmp_path / "o.ttproj")
    assert main(["convert", str(photo), out, "--tile", "32", "--tls-cert", tls.cert]) == 2
    assert "are for --scheduler tls://" in capsys.readouterr().err
    assert main(["convert", str(photo), out, "--tile", "32", "--scheduler", "tls://127.0.0.1:1",
                 "--tls-cert", tls.cert]) == 2
    assert "give --tls-ca-file and --tls-cert" in capsys.readouterr().err
