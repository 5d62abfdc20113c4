"""Where a fleet's records run on Dask: a private local cluster, or a scheduler the user names.

The local cluster belongs to the user who runs the fleet.  Dask executes
any function a connected client sends, so whoever can connect to a
cluster runs code as its owner.  Here the scheduler, the nannies and the
workers listen on 127.0.0.1 only and speak TLS with a key and a
self-signed certificate generated for this run and held in memory
(:meth:`distributed.security.Security.temporary`); each side of every
connection must present that certificate, so another user of the machine
who finds a port cannot connect.  The HTTP servers Dask starts with every
scheduler and worker get no pages and are stopped once the cluster is up
(a worker its nanny restarts has one again, still without pages): no
dashboard, unless asked for (then on 127.0.0.1, with Dask's pages).

A scheduler given by address is used only as the user says: ``tls://``
with the TLS files given (or those in Dask's configuration,
``distributed.comm.tls.*``); plain ``tcp://`` — where anyone who can
reach the port runs code as the user — only with ``insecure=True``.

Dask's own logging (a worker's heartbeat traceback as the cluster shuts
down, memory notes) is quiet during the run unless ``verbose``.
"""

from __future__ import annotations

import logging
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any
from urllib.parse import urlsplit

from .._errors import OptionError, OptionTypeError

__all__ = ["check_scheduler", "connect", "dashboard_link", "quiet_dask", "start_local",
           "tls_security"]

_DEFAULT_PORT = 8786
_DASHBOARD = "127.0.0.1:8787"
_PRIVATE = {"distributed.scheduler.http.routes": [], "distributed.worker.http.routes": []}
# the loggers Dask configures (distributed/config.py) and the event loop's
_LOGGERS = ("distributed", "tornado", "asyncio", "bokeh")
_QUIET = logging.CRITICAL  # a successful run logs nothing at this level
_SCHEMES = "tls:// (or tcp:// with --insecure)"
_NO_DASK = ("running a fleet on a Dask scheduler needs Dask: pip install 'servoid[fleet]', or "
            "pass --workers 1 for a serial run")


def check_scheduler(address: Any, security: Any = None, insecure: bool = False) -> str:
    """Check a scheduler address and the security it is used with, before any work.

    Parameters
    ----------
    address : str
        ``tls://host:port`` or ``tcp://host:port`` (port default 8786).
    security : distributed.security.Security, optional
        The TLS settings for a ``tls://`` scheduler; default: Dask's
        configuration.
    insecure : bool
        Accept a plain ``tcp://`` scheduler.

    Returns
    -------
    str
        The address with its scheme (``tcp://`` when none was written).
    """
    if not isinstance(address, str):
        raise OptionTypeError(f"scheduler must be an address like tls://host:8786 "
                              f"(--scheduler); got {address!r}")
    if not isinstance(insecure, bool):
        raise OptionTypeError(f"insecure must be True or False; got {insecure!r}")
    shown = repr(address)
    if not address.strip() or any(ord(c) < 32 or c.isspace() for c in address):
        raise OptionError(f"--scheduler {shown} is not an address: give one like "
                          "tls://host:8786, without spaces or control characters")
    text = address if "://" in address else f"tcp://{address}"
    scheme = text.split("://", 1)[0].lower()
    if scheme not in ("tls", "tcp"):
        raise OptionError(f"--scheduler {shown}: servoid connects to a Dask scheduler over "
                          f"{_SCHEMES}; {scheme}:// (UCX, websockets, in-process) is not "
                          "supported: start the scheduler with --protocol tls")
    try:
        parts = urlsplit(text)
        host, port = parts.hostname, parts.port
    except ValueError as exc:
        raise OptionError(f"--scheduler {shown} is not an address ({exc}): give "
                          "tls://host:port with a port from 1 to 65535") from None
    if not host or parts.path not in ("", "/") or parts.query or parts.fragment \
            or parts.username is not None or port == 0:
        raise OptionError(f"--scheduler {shown} is not an address: give tls://host:port "
                          "(a host name or IP address and a port from 1 to 65535)")
    if security is not None:
        _check_security(security)
    if scheme == "tcp":
        if security is not None:
            raise OptionError(f"--scheduler {shown} is plain tcp://, but TLS settings were "
                              "given: write the address as tls://host:port")
        if not insecure:
            raise OptionError(
                f"--scheduler {shown} is plain tcp://: whoever can reach that port can run "
                "code as you on the workers. Use a scheduler started with --protocol tls and "
                "give its TLS files (--tls-ca-file, --tls-cert, --tls-key), or, on a network "
                "only you can reach, pass --insecure (insecure=True)")
    elif security is None:
        try:
            from distributed.security import Security  # the TLS files in Dask's configuration
        except ImportError:
            raise OptionError(_NO_DASK) from None
        configured = Security()
        if not configured.tls_ca_file or not configured.tls_client_cert:
            raise OptionError(
                f"--scheduler {shown} is tls://, which needs the cluster's CA certificate "
                "and a client certificate and key: give --tls-ca-file, --tls-cert and "
                "--tls-key, or set distributed.comm.tls.ca-file and "
                "distributed.comm.tls.client.cert/key in Dask's configuration")
    host = f"[{host}]" if ":" in host else host
    return f"{scheme}://{host}:{port or _DEFAULT_PORT}"


def tls_security(ca_file: Any, cert: Any, key: Any = None) -> Any:
    """TLS settings for a ``tls://`` scheduler, from PEM files.

    Pass the result as ``security`` to :func:`servoid.fleet.run_fleet`.

    Parameters
    ----------
    ca_file : path
        The cluster's CA certificate (PEM).
    cert : path
        This client's certificate (PEM); it may hold the key too.
    key : path, optional
        This client's private key (PEM), when not in `cert`.

    Returns
    -------
    distributed.security.Security
        Encryption required; the files are read when connecting.
    """
    names = {"--tls-ca-file": ca_file, "--tls-cert": cert, "--tls-key": key}
    for flag, path in names.items():
        if path is None and flag != "--tls-key":
            raise OptionError(f"a tls:// scheduler needs {flag}: give --tls-ca-file and "
                              "--tls-cert (and --tls-key when the key is a separate file)")
        if path is not None:
            _check_pem(flag, path)
    try:
        from distributed.security import Security
    except ImportError:
        raise OptionError(_NO_DASK) from None
    return Security(tls_ca_file=os.fspath(ca_file), tls_client_cert=os.fspath(cert),
                    tls_client_key=None if key is None else os.fspath(key),
                    require_encryption=True)


def connect(address: str, security: Any = None) -> Any:
    """A client of the scheduler at a checked `address` (see :func:`check_scheduler`)."""
    try:
        from distributed import Client
        from distributed.security import Security
    except ImportError:
        raise OptionError(_NO_DASK) from None
    if security is None:
        security = Security()  # tls:// checked to have files in Dask's configuration
    try:
        return Client(address, security=security, timeout="10s")
    except Exception as exc:  # noqa: BLE001 - Dask, ssl and asyncio raise many kinds here
        raise OptionError(f"cannot connect to the Dask scheduler at {address} "
                          f"({type(exc).__name__}: {exc}); check that it runs, the address "
                          "and the TLS files, or drop --scheduler to use a local "
                          "cluster") from None


def start_local(n: int, *, dashboard: bool, verbose: bool,
                config: dict[str, Any], env: dict[str, str]) -> tuple[Any, Any]:
    """Start a private local cluster of `n` single-threaded worker processes.

    Returns
    -------
    cluster, client
        The cluster and a client connected to it over TLS.
    """
    import dask
    from distributed import Client, LocalCluster
    from distributed.security import Security

    try:
        security = Security.temporary()
    except ImportError:
        raise OptionError("the local Dask cluster is secured with TLS, which needs the "
                          "cryptography package: pip install 'servoid[fleet]', or pass "
                          "--workers 1 for a serial run") from None
    private = dict(_PRIVATE)
    if dashboard:
        del private["distributed.scheduler.http.routes"]  # Dask's own pages
    with dask.config.set({**config, **private}):
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
            protocol="tls://", security=security,
            # never Dask's default, which binds :8787 even when the dashboard is off
            dashboard_address=_DASHBOARD if dashboard else "127.0.0.1:0",
            scheduler_kwargs={"dashboard": dashboard},
            silence_logs=logging.WARNING if verbose else _QUIET, env=env)
    try:
        client = Client(cluster)
        client.run(_stop_http)
        if not dashboard:
            client.run_on_scheduler(_stop_http)
    except BaseException:
        cluster.close()
        raise
    return cluster, client


def dashboard_link(cluster: Any) -> str | None:
    """The dashboard's address, when the cluster has one."""
    try:
        return str(cluster.dashboard_link)
    except Exception:  # noqa: BLE001 - no dashboard
        return None


@contextmanager
def quiet_dask(verbose: bool, used: bool = True) -> Iterator[None]:
    """Keep Dask's logging in this process quiet for the block, unless `verbose`.

    Dask sets its loggers' levels when it is imported, so it is imported
    first (when `used` and installed).
    """
    if verbose or not used or not _imported():
        yield
        return
    manager = logging.Logger.manager
    loggers = [logging.getLogger(name) for name in _LOGGERS]
    loggers += [lg for name, lg in list(manager.loggerDict.items())
                if isinstance(lg, logging.Logger) and name.split(".")[0] in _LOGGERS
                and lg.level != logging.NOTSET]
    saved = [(lg, lg.level) for lg in dict.fromkeys(loggers)]
    for lg, level in saved:
        lg.setLevel(max(level, _QUIET))
    try:
        yield
    finally:
        for lg, level in saved:
            lg.setLevel(level)


def _imported() -> bool:
    try:
        import distributed  # noqa: F401 - configures its loggers, which are then turned down
    except ImportError:
        return False
    return True


async def _stop_http(dask_worker: Any = None, dask_scheduler: Any = None) -> None:
    """Stop a worker's or the scheduler's HTTP server (it serves no page here)."""
    server = getattr(dask_worker or dask_scheduler, "http_server", None)
    if server is not None:
        server.stop()


def _check_security(security: Any) -> None:
    try:
        from distributed.security import Security
    except ImportError:  # pragma: no cover - a Security object implies Dask
        return
    if not isinstance(security, Security):
        raise OptionTypeError(f"security must be a distributed.security.Security; got "
                              f"{type(security).__name__}")


def _check_pem(flag: str, path: Any) -> None:
    if not isinstance(path, str | os.PathLike):
        raise OptionTypeError(f"{flag} must be a file name; got {path!r}")
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError) as exc:
        raise OptionError(f"{flag} {os.fspath(path)!r} cannot be read "
                          f"({getattr(exc, 'strerror', None) or exc}); give the PEM file's "
                          "path") from None
    if not stat.S_ISREG(mode):
        raise OptionError(f"{flag} {os.fspath(path)!r} is not a regular file; give the PEM "
                          "file's path")
