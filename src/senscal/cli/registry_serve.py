"""``senscal registry serve``: the read-only web view of the registry (see :mod:`senscal.registry.web`)."""

from __future__ import annotations

from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli.cmd_registry import registry_app
from senscal.cli.common import err_console, parse_relative
from senscal.cli.registry_opts import DbOpt
from senscal.errors import InputError


@registry_app.command("serve")
def serve_cmd(
    db: DbOpt = None,
    port: Annotated[int, typer.Option("--port", help="TCP port (0: any free port, printed).")] = 8000,
    host: Annotated[str, typer.Option(
        "--host", help="Interface to listen on; anything but this computer's loopback needs --allow-remote.")]
    = "127.0.0.1",
    allow_remote: Annotated[bool, typer.Option(
        "--allow-remote", help="Listen on a --host other machines reach: the view has no login and no TLS, so "
                               "everyone who reaches it reads the registry.")] = False,
    tolerance: Annotated[Optional[str], typer.Option(
        "--tolerance", help="Relative tolerance of every quantity for due dates, 1% or 0.01, as 'registry due' "
                            "(default: drift only, no due dates).")] = None,
    k: Annotated[float, typer.Option("--k", help="Coverage factor added to the predicted deviation.")] = 2.0,
    soon: Annotated[int, typer.Option("--soon", metavar="DAYS", help="Mark due dates within DAYS as 'due soon'.")] = 30,
    as_of: Annotated[Optional[str], typer.Option(
        "--as-of", metavar="ISO", help="Judge due and overdue at this date (ISO 8601; default: now, at each page).")]
    = None,
) -> None:
    """Read-only web view of the registry: sensors and standards with due dates, history plots and drift,
    calibrations with their certificates, the hash-chain status (127.0.0.1:8000 by default)."""
    import math

    from senscal.registry import parse_date
    from senscal.registry.web.server import check_port, is_loopback

    # Every option is checked before the database is opened or a port bound.
    check_port(port)
    tol = None
    if tolerance is not None:
        tol = parse_relative(tolerance, "--tolerance")
        if tol == 0:
            raise InputError("--tolerance must be larger than zero")
    if not (math.isfinite(k) and k > 0):
        raise InputError(f"--k must be a positive, finite coverage factor, got {k}")
    if soon < 0:
        raise InputError(f"--soon must be a number of days, 0 or more, got {soon}")
    when = parse_date(as_of, what="--as-of") if as_of is not None else None
    local = is_loopback(host)
    if not local and not allow_remote:
        raise InputError(f"--host {host} lets other machines read the registry (no login, no TLS); add "
                         "--allow-remote to mean it, or keep the default 127.0.0.1")
    from senscal.registry.web import LOCAL_HOSTS, ViewOptions, create_app, make_server, open_read_only

    reg = open_read_only(db)
    try:
        bare = host.strip().strip("[]")
        # The name the user chose is answered too (127.0.0.2, a local alias), in brackets for IPv6.
        trusted = (*LOCAL_HOSTS, bare, f"[{bare}]" if ":" in bare else bare) if local else None
        app = create_app(reg, ViewOptions(tolerance=tol, k=k, as_of=when, soon_days=soon), trusted_hosts=trusted)
        server = make_server(app, host, port)
        shown = f"[{host.strip('[]')}]" if ":" in host else host
        err_console.print(f"serving {reg.url} read-only at http://{shown}:{server.port}/ (Ctrl+C stops)",
                          highlight=False, soft_wrap=True)
        _stop_on_interrupt()
        try:
            server.serve_forever()
        except KeyboardInterrupt:
            pass
        finally:
            server.server_close()
    finally:
        reg.close()


def _stop_on_interrupt() -> None:
    """Ctrl+C and SIGTERM stop the server, whatever the parent left behind.

    A process started with SIGINT ignored (by a job runner, ``nohup`` or a
    test worker) inherits that, and Python then leaves Ctrl+C ignored: the
    view would run until killed, without closing its database.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return

    def stop(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, stop)
    if hasattr(signal, "SIGTERM"):
        signal.signal(signal.SIGTERM, stop)
