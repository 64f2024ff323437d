"""Serving the web view: bind checks and the HTTP server (werkzeug's threaded WSGI server).

The registry view is a single-user, read-only page server for the lab's own
computer: werkzeug's server (the one Flask ships) answers it, one thread per
request.  Binding anywhere but the loopback interface shows the registry,
without a login or TLS, to every machine that reaches this one; the command
line asks for that to be said explicitly (``--allow-remote``).
"""

from __future__ import annotations

import errno
import ipaddress
import socket

from senscal.errors import InputError

__all__ = ["is_loopback", "check_port", "make_server"]


def check_port(port: int) -> int:
    """``port`` if it is a TCP port number (0 asks the system for a free one), else InputError."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise InputError(f"--port must be a TCP port from 1 to 65535 (0: any free port), got {port}")
    return port


def is_loopback(host: str) -> bool:
    """Whether every address ``host`` names is a loopback address (127.0.0.0/8, ::1).

    Raises
    ------
    InputError
        ``host`` is empty or does not resolve.
    """
    text = str(host).strip().strip("[]")
    if not text:
        raise InputError("--host must name an interface, e.g. 127.0.0.1 (the default) or localhost")
    try:
        return ipaddress.ip_address(text).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(text, None, proto=socket.IPPROTO_TCP)
    except (socket.gaierror, UnicodeError) as exc:
        raise InputError(f"--host {host!r} does not resolve ({getattr(exc, 'strerror', None) or exc}); give an "
                         "address such as 127.0.0.1 or a name this computer knows") from None
    addrs = {ipaddress.ip_address(info[4][0].split("%")[0]) for info in infos}
    return bool(addrs) and all(a.is_loopback for a in addrs)


def make_server(app, host: str = "127.0.0.1", port: int = 8000):
    """Bind ``app`` to ``host:port`` (threaded) and return the server; ``serve_forever()`` runs it.

    Raises
    ------
    InputError
        The port is taken, needs privileges, or the address is not this computer's.
    """
    from werkzeug.serving import WSGIRequestHandler
    from werkzeug.serving import make_server as _make_server

    class _Quiet(WSGIRequestHandler):
        # One line per request on stderr would bury the address the command printed; errors still print.
        def log_request(self, *args, **kwargs) -> None:
            pass

    check_port(port)
    addr = str(host).strip().strip("[]")
    # The socket is bound here, not by werkzeug: its server prints to stderr and exits 1 on a bind error.
    try:
        family = socket.AF_INET6 if ":" in addr else socket.AF_INET
        if family == socket.AF_INET:
            try:
                ipaddress.IPv4Address(addr)
            except ValueError:
                infos = socket.getaddrinfo(addr, port, socket.AF_UNSPEC, socket.SOCK_STREAM)
                family, addr = infos[0][0], infos[0][4][0]
        sock = socket.socket(family, socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as exc:
        raise InputError(f"cannot listen on {host}:{port}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((addr, port))
        sock.listen(128)
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            why = f"port {port} on {host} is in use; choose another --port (or --port 0 for any free one)"
        elif exc.errno in (errno.EACCES, errno.EPERM):
            why = f"port {port} on {host} needs administrator rights; choose a --port from 1024 up"
        elif exc.errno == errno.EADDRNOTAVAIL:
            why = f"{host} is not an address of this computer; give --host 127.0.0.1 or one of its own addresses"
        else:
            why = f"cannot listen on {host}:{port}: {exc.strerror or exc}"
        raise InputError(why) from None
    try:
        server = _make_server(addr, sock.getsockname()[1], app, threaded=True, request_handler=_Quiet,
                              fd=sock.fileno())
    finally:
        sock.close()  # werkzeug works on its own duplicate of the descriptor
    return server
