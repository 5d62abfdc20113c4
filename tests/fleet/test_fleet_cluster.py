"""The fleet's Dask cluster is its owner's alone; a scheduler by address only as the user says.

Whoever can connect to a Dask cluster runs code in its workers.  The local
cluster must therefore accept only the credentials made for its run, on
127.0.0.1, serve no HTTP page (no dashboard unless asked) and keep Dask's
logging quiet; an address is used only with the security it needs.
"""

from __future__ import annotations

import asyncio
import logging
import re
import socket
import urllib.request

import pytest
from _arx_fleet import write_fleet, write_pem

import servoid.fleet._run as fleet_run
from servoid import OptionError, OptionTypeError
from servoid.fleet import run_fleet, tls_security
from servoid.fleet._cluster import check_scheduler, quiet_dask

distributed = pytest.importorskip("distributed")
pytest.importorskip("cryptography")
psutil = pytest.importorskip("psutil")


@pytest.fixture(scope="module")
def private():
    """A local cluster of two workers, started the way a fleet starts it."""
    pool = fleet_run._Pool(None, 2, 2)
    client = pool.client(2)
    yield pool, client
    pool.close()


def _listening() -> set[tuple[str, int]]:
    """TCP ports this process and its children listen on."""
    me = psutil.Process()
    return {(c.laddr.ip, c.laddr.port) for p in (me, *me.children(recursive=True))
            for c in p.net_connections("tcp") if c.status == psutil.CONN_LISTEN}


def _identity(address: str, security=None) -> dict:
    """Ask a Dask server who it is: the first thing a client does."""
    from distributed.comm import connect

    async def ask() -> dict:
        args = security.get_connection_args("client") if security is not None else {}
        comm = await connect(address, timeout=3, **args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            await comm.close()

    return asyncio.run(ask())


def _http_answer(port: int) -> bytes:
    """The first bytes a server answers to a plain HTTP request."""
    with socket.create_connection(("127.0.0.1", port), timeout=3) as s:
        s.sendall(b"GET /info/main/workers.html HTTP/1.0\r\nHost: x\r\n\r\n")
        try:
            return s.recv(64)
        except OSError:  # reset: not an HTTP server
            return b""


def test_local_cluster_answers_only_its_own_credentials(private):
    from distributed.security import Security

    pool, client = private
    assert client.scheduler.address.startswith("tls://127.0.0.1:")
    ports = _listening()
    assert ports and {ip for ip, _ in ports} == {"127.0.0.1"}
    assert 8787 not in {port for _, port in ports}  # Dask's default dashboard port
    stranger = Security.temporary()  # another user's own certificate
    for _, port in sorted(ports):
        own = _identity(f"tls://127.0.0.1:{port}", client.security)  # the probe can succeed
        assert own["type"] in ("Scheduler", "Worker", "Nanny"), own
        with pytest.raises(Exception, match="(?i)certificate|closed|timed out"):
            _identity(f"tls://127.0.0.1:{port}", stranger)
        with pytest.raises(Exception, match="(?i)closed|timed out|reset"):
            _identity(f"tcp://127.0.0.1:{port}")
        assert not _http_answer(port).startswith(b"HTTP/")  # no page, no dashboard
    assert client.submit(sum, [1, 2]).result() == 3


def test_a_tls_scheduler_is_used_with_the_files_given(private, tmp_path):
    pool, client = private
    pem = write_pem(client, tmp_path)
    fleet = write_fleet(tmp_path / "f", ["A", "B", "C"])
    address = pool._cluster.scheduler_address
    served = run_fleet(fleet, tmp_path / "tls", scheduler=address, progress=False,
                       security=tls_security(pem["ca"], pem["cert"], pem["key"]))
    serial = run_fleet(fleet, tmp_path / "serial", workers=1, progress=False)
    assert served.count("ok") == 3
    assert [r["a1"] for r in served.rows] == [r["a1"] for r in serial.rows]
    with pytest.raises(OptionError, match="needs the cluster's CA certificate"):
        run_fleet(fleet, tmp_path / "none", scheduler=address, progress=False)
    plain = address.replace("tls://", "tcp://")
    with pytest.raises(OptionError, match="plain tcp://"):
        run_fleet(fleet, tmp_path / "tcp", scheduler=plain, progress=False)
    with pytest.raises(OptionError, match="cannot connect to the Dask scheduler"):
        run_fleet(fleet, tmp_path / "tcp", scheduler=plain, insecure=True, progress=False)


def test_dashboard_only_when_asked_and_on_loopback(capfd):
    pool = fleet_run._Pool(None, 2, 2, dashboard=True)
    try:
        pool.client(2)
        link = re.search(r"Dask dashboard: http://127\.0\.0\.1:(\d+)/", capfd.readouterr().err)
        assert link is not None
        url = f"http://127.0.0.1:{link[1]}/info/main/workers.html"
        with urllib.request.urlopen(url, timeout=10) as page:
            assert page.status == 200
    finally:
        pool.close()


@pytest.mark.parametrize("verbose", [False, True])
def test_dask_logging_is_quiet_unless_verbose(capfd, verbose):
    """An error a worker logs (a heartbeat failing at shutdown) shows only with verbose."""
    def log() -> None:
        logging.getLogger("distributed.worker").error("heartbeat to the scheduler failed")

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            kept.append(record.getMessage())

    kept: list[str] = []
    client_log = logging.getLogger("distributed.client")  # this process's, with its own level
    client_log.addHandler(keep := Keep())
    try:
        with quiet_dask(verbose):
            pool = fleet_run._Pool(None, 2, 2, verbose=verbose)
            try:
                pool.client(2).run(log)
                client_log.warning("the client lost the scheduler")
            finally:
                pool.close()
    finally:
        client_log.removeHandler(keep)
    assert ("heartbeat to the scheduler failed" in capfd.readouterr().err) is verbose
    assert ("the client lost the scheduler" in kept) is verbose


@pytest.mark.parametrize(
    ("address", "fragment"),
    [
        ("ucx://127.0.0.1:8786", "ucx:// (UCX, websockets, in-process) is not supported"),
        ("inproc://x", "inproc:// (UCX"),
        ("tls://", "is not an address"),
        ("tls://:8786", "is not an address"),
        ("tls://host:99999", "port from 1 to 65535"),
        ("tls://host:0", "is not an address"),
        ("tls://host:port", "port from 1 to 65535"),
        ("tls://host:8786/path", "is not an address"),
        ("tls://user@host:8786", "is not an address"),
        ("tls://[::1", "is not an address"),
        ("", "is not an address"),
        ("tls://ho st:1", "without spaces"),
        ("tls://host\x00:1", "control characters"),
        ("tcp://127.0.0.1:8786", "plain tcp://"),
        ("127.0.0.1:8786", "plain tcp://"),
    ],
)
def test_bad_scheduler_addresses_say_what_is_wrong(address, fragment):
    with pytest.raises(OptionError) as err:
        check_scheduler(address)
    assert fragment in str(err.value)


def test_scheduler_address_rules():
    import dask

    assert check_scheduler("TCP://Host:1", insecure=True) == "tcp://host:1"
    assert check_scheduler("host", insecure=True) == "tcp://host:8786"  # Dask's default port
    assert check_scheduler("tcp://[::1]:9", insecure=True) == "tcp://[::1]:9"
    with dask.config.set({"distributed.comm.tls.ca-file": "ca.pem",
                          "distributed.comm.tls.client.cert": "cert.pem"}):
        assert check_scheduler("tls://h:1") == "tls://h:1"  # Dask's configuration is used
    with pytest.raises(OptionTypeError, match="scheduler must be an address"):
        check_scheduler(8786)
    with pytest.raises(OptionTypeError, match="distributed.security.Security"):
        check_scheduler("tls://h:1", security={"ca": "x"})
    with pytest.raises(OptionError, match="write the address as tls://"):
        check_scheduler("tcp://h:1", security=distributed.security.Security(), insecure=True)


def test_tls_files_are_checked(tmp_path):
    import os

    (tmp_path / "ca.pem").write_text("x", encoding="utf-8")
    os.mkfifo(tmp_path / "fifo.pem")
    with pytest.raises(OptionError, match="--tls-cert 'missing.pem' cannot be read"):
        tls_security(tmp_path / "ca.pem", "missing.pem")
    with pytest.raises(OptionError, match="fifo.pem' is not a regular file"):
        tls_security(tmp_path / "ca.pem", tmp_path / "fifo.pem")
    with pytest.raises(OptionError, match="needs --tls-cert"):
        tls_security(tmp_path / "ca.pem", None)
    security = tls_security(tmp_path / "ca.pem", tmp_path / "ca.pem")
    assert security.require_encryption


def test_flags_that_need_a_scheduler_or_a_cluster(tmp_path):
    fleet = write_fleet(tmp_path, ["A", "B"])
    with pytest.raises(OptionError, match="apply to a scheduler given by address"):
        run_fleet(fleet, insecure=True, progress=False)
    with pytest.raises(OptionError, match="without one"):
        run_fleet(fleet, workers=1, dashboard=True, progress=False)
    with pytest.raises(OptionError, match="serves its own dashboard"):
        run_fleet(fleet, scheduler="tls://h:1", dashboard=True, progress=False)
    with pytest.raises(OptionTypeError, match="verbose must be True or False"):
        run_fleet(fleet, workers=1, verbose="yes", progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.toml", "units", "units.csv"]
