"""A live meshcat server bound to 127.0.0.1 only, in a thread of the calling process.

meshcat 0.3.2's ``ZMQWebSocketBridge`` binds its ZMQ socket to its ``host`` (127.0.0.1 by
default) but starts its web server with ``Application.listen(port)``, which listens on every
interface: anyone on the network could watch (and the viewer's websocket accepts commands).
:class:`LoopbackMeshcatServer` subclasses the bridge so the web server listens on the same
loopback host, and runs it in a daemon thread of this process instead of meshcat's
``meshcat-server`` subprocess: nothing outlives the process, and :meth:`stop` (or leaving the
``with`` block, Ctrl-C included) closes both sockets.

Binding to loopback is not enough against DNS rebinding: a web page from another site can make
the browser resolve its own name to 127.0.0.1 and then read the viewer or drive its websocket.
Every request (page and websocket) must therefore carry a loopback ``Host`` header
(``127.0.0.1``, ``localhost`` or ``[::1]``, with the server's port); any other gets 403. The
websocket also refuses a non-loopback ``Origin``.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
from typing import Any
from urllib.parse import urlsplit

import tornado.web
import tornado.websocket
import zmq
from meshcat.servers import zmqserver

from ident.errors import IdentError
from ident.viz.recorder import SceneRecorder

__all__ = ["DEFAULT_PORT", "LoopbackMeshcatServer", "find_free_port", "is_loopback_host"]

DEFAULT_PORT = 7000  # meshcat's default web port
_LOOPBACK = "127.0.0.1"
_PORT_ATTEMPTS = 100
_REPLY_TIMEOUT_MS = 10_000
_LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")


class ServerError(IdentError):
    """The live meshcat server could not start or did not answer."""


def is_loopback_host(host: str | None, port: int | None) -> bool:
    """True if an HTTP ``Host`` header names this machine's loopback (and ``port``, if given).

    ``127.0.0.1``, ``localhost`` and ``[::1]`` are accepted, case-insensitively, without a
    port or with ``port``; anything else (a DNS name that resolves to 127.0.0.1 included) is not.
    """
    if not host:
        return False
    text = host.strip().lower()
    if text.startswith("["):  # IPv6 literal, "[::1]" or "[::1]:7000"
        end = text.find("]")
        if end < 0:
            return False
        name, rest = text[: end + 1], text[end + 1 :]
    else:
        name, sep, port_text = text.partition(":")
        rest = sep + port_text
    if name not in _LOOPBACK_NAMES:
        return False
    if not rest:
        return True
    if not (rest.startswith(":") and rest[1:].isdigit()):
        return False
    return port is None or int(rest[1:]) == port


def _is_loopback_origin(origin: str, port: int | None) -> bool:
    parts = urlsplit(origin)
    return parts.scheme in ("http", "https") and is_loopback_host(parts.netloc, port)


def find_free_port(start: int, host: str = _LOOPBACK, attempts: int = _PORT_ATTEMPTS) -> int:
    """First port >= ``start`` where a TCP server can listen on ``host``.

    ``start = 0`` asks the system for any free port (and returns its number).

    Raises
    ------
    ServerError
        ``start`` outside 0..65535, or no free port among ``attempts`` consecutive ports.
    """
    if isinstance(start, bool) or not isinstance(start, int) or not 0 <= start <= 65535:
        raise ServerError(f"--port {start!r}: give a port in 0..65535 (0: any free port).")
    if start == 0:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            probe.bind((host, 0))
            return int(probe.getsockname()[1])
    for port in range(start, min(start + attempts, 65536)):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            try:
                probe.bind((host, port))
            except OSError:
                continue
            return port
    raise ServerError(
        f"no free TCP port on {host} in {start}..{start + attempts - 1}; choose another --port."
    )


class _LoopbackApplication(tornado.web.Application):
    """Tornado application whose ``listen`` binds to one host and keeps its server."""

    def __init__(self, handlers: list[Any], host: str) -> None:
        super().__init__(handlers)
        self.host = host
        self.port: int | None = None
        self.http_server: Any = None

    def listen(self, port: int, address: str | None = None, **kwargs: Any) -> Any:
        """Listen on ``self.host`` whatever address the caller passes (meshcat passes none)."""
        self.port = port
        self.http_server = super().listen(port, address=self.host, **kwargs)
        return self.http_server

    def find_handler(self, request: Any, **kwargs: Any) -> Any:
        """Route only requests with a loopback ``Host`` header; others get 403."""
        if not is_loopback_host(request.host, getattr(self, "port", None)):
            return self.get_handler_delegate(request, _Forbidden)
        return super().find_handler(request, **kwargs)


class _Forbidden(tornado.web.RequestHandler):
    """403 for a request whose Host header is not this machine's loopback (DNS rebinding)."""

    def prepare(self) -> None:
        raise tornado.web.HTTPError(403, reason="Host not allowed")


class _QuietWebSocketHandler(zmqserver.WebSocketHandler):
    """meshcat's websocket handler without its 'opened:'/'closed:' prints."""

    def open(self) -> None:
        self.bridge.websocket_pool.add(self)
        self.bridge.send_scene(self)

    def on_close(self) -> None:
        self.bridge.websocket_pool.discard(self)

    def check_origin(self, origin: str) -> bool:
        """Accept a websocket only from a page served on loopback."""
        return _is_loopback_origin(origin, getattr(self.application, "port", None))


class _NoFavicon(tornado.web.RequestHandler):
    """Answer browsers' /favicon.ico with 204 (meshcat's 404 shows as a console error)."""

    def get(self) -> None:
        self.set_status(204)


class _LoopbackBridge(zmqserver.ZMQWebSocketBridge):
    """meshcat's ZMQ <-> websocket bridge with both sockets on ``self.host``.

    A browser tab that closes while the scene is sent is dropped without a word (meshcat's
    bridge let tornado print a ``WebSocketClosedError`` traceback per message).
    """

    def _send(self, websocket: Any, data: bytes) -> None:
        """Send one binary message; a closed websocket leaves the pool quietly."""
        try:
            future = websocket.write_message(data, binary=True)
        except tornado.websocket.WebSocketClosedError:
            self.websocket_pool.discard(websocket)
            return
        if future is not None:
            future.add_done_callback(lambda f: self._sent(websocket, f))

    def _sent(self, websocket: Any, future: Any) -> None:
        """Retrieve a send's outcome (an unretrieved failure prints a traceback)."""
        if not future.cancelled() and future.exception() is not None:
            self.websocket_pool.discard(websocket)

    def forward_to_websockets(self, frames: list[bytes]) -> None:
        """Send a command to every connected browser."""
        _, _, data = frames
        for websocket in list(self.websocket_pool):
            self._send(websocket, data)

    def send_scene(self, websocket: Any) -> None:
        """Send the whole scene to a browser that just connected."""
        for node in zmqserver.walk(self.tree):
            messages = [node.object, *node.properties, node.transform, node.animation]
            for data in messages:
                if data is not None:
                    self._send(websocket, data)

    def make_app(self) -> _LoopbackApplication:
        return _LoopbackApplication(
            [
                (
                    r"/static/(.*)",
                    zmqserver.StaticFileHandlerNoCache,
                    {"path": zmqserver.VIEWER_ROOT, "default_filename": zmqserver.VIEWER_HTML},
                ),
                (r"/", _QuietWebSocketHandler, {"bridge": self}),
                (r"/favicon.ico", _NoFavicon),
            ],
            host=self.host,
        )


class LoopbackMeshcatServer:
    """meshcat server on 127.0.0.1 in a daemon thread; use as a context manager.

    Parameters
    ----------
    port :
        First web port to try; the next free one is taken when it is in use.

    Attributes
    ----------
    web_url :
        Page of the viewer, ``http://127.0.0.1:<port>/static/``.
    port, zmq_url :
        Web port and ZMQ endpoint (``tcp://127.0.0.1:<port>``) once started.
    """

    def __init__(self, port: int = DEFAULT_PORT) -> None:
        self.requested_port = port
        self.port: int | None = None
        self.web_url = ""
        self.zmq_url = ""
        self._bridge: _LoopbackBridge | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None

    def start(self) -> LoopbackMeshcatServer:
        """Start the server thread and wait until both sockets listen."""
        self.port = find_free_port(self.requested_port)
        self._thread = threading.Thread(target=self._serve, name="meshcat-server", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout=20.0):
            raise ServerError("the meshcat server did not start within 20 s.")
        if self._error is not None:
            raise ServerError(
                f"cannot start the meshcat server on {_LOOPBACK}:{self.port}: {self._error}"
            ) from self._error
        assert self._bridge is not None
        self.zmq_url = self._bridge.zmq_url
        self.web_url = self._bridge.web_url
        return self

    def _serve(self) -> None:
        asyncio.set_event_loop(asyncio.new_event_loop())
        try:
            # zmq_url=None: meshcat takes the first free ZMQ port from 6000 on self.host.
            self._bridge = _LoopbackBridge(host=_LOOPBACK, port=self.port)
        except BaseException as e:  # reported by start() in the calling thread
            self._error = e
            self._ready.set()
            return
        self._ready.set()
        bridge = self._bridge
        try:
            bridge.run()
        finally:
            # Runs in the server thread, after stop(): close every socket of the bridge.
            for ws in list(bridge.websocket_pool):
                ws.close()
            if bridge.app.http_server is not None:
                bridge.app.http_server.stop()
            bridge.zmq_stream.close(linger=0)
            bridge.ioloop.close(all_fds=True)

    def push(self, recorder: SceneRecorder) -> None:
        """Send a recorded scene to the server (and to every connected browser)."""
        if self._bridge is None:
            raise ServerError("push() before start().")
        context: Any = zmq.Context.instance()
        with contextlib.closing(context.socket(zmq.REQ)) as sock:
            sock.setsockopt(zmq.LINGER, 0)
            sock.setsockopt(zmq.RCVTIMEO, _REPLY_TIMEOUT_MS)
            sock.connect(self.zmq_url)
            for command in recorder.commands:
                sock.send_multipart([command.type.encode(), command.path.encode(), command.data])
                try:
                    reply = sock.recv()
                except zmq.Again as e:
                    raise ServerError(
                        f"the meshcat server at {self.zmq_url} did not answer within "
                        f"{_REPLY_TIMEOUT_MS / 1000:.0f} s."
                    ) from e
                if reply != b"ok":
                    raise ServerError(f"the meshcat server refused a command: {reply!r}")

    def stop(self) -> None:
        """Stop the server and close its sockets; safe to call twice."""
        if self._thread is None:
            return
        if self._bridge is not None and self._thread.is_alive():
            ioloop = self._bridge.ioloop
            ioloop.add_callback(ioloop.stop)
        self._thread.join(timeout=10.0)
        self._thread = None

    def __enter__(self) -> LoopbackMeshcatServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
