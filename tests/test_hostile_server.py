"""The live replay server answers only loopback Host headers (DNS-rebinding guard)."""

import http.client

import pytest

from ident.viz.server import LoopbackMeshcatServer, ServerError, find_free_port, is_loopback_host


@pytest.mark.parametrize(
    ("host", "ok"),
    [
        ("127.0.0.1:7000", True),
        ("localhost:7000", True),
        ("LocalHost:7000", True),
        ("[::1]:7000", True),
        ("127.0.0.1", True),
        ("[::1]", True),
        ("127.0.0.1:7001", False),  # another port
        ("evil.example:7000", False),  # a rebound name
        ("127.0.0.1.evil.example:7000", False),
        ("localhost.:7000", False),
        ("::1", False),
        ("[::1", False),
        ("localhost:", False),
        ("127.0.0.1:7000x", False),
        ("", False),
        (None, False),
    ],
)
def test_loopback_host_allow_list(host, ok):
    assert is_loopback_host(host, 7000) is ok


def _get(port: int, host: str | None, path: str = "/static/") -> int:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    try:
        conn.putrequest("GET", path, skip_host=True)
        if host is not None:
            conn.putheader("Host", host)
        conn.endheaders()
        return conn.getresponse().status
    finally:
        conn.close()


def test_server_port_zero_gives_real_port_and_refuses_foreign_hosts():
    with LoopbackMeshcatServer(port=0) as server:
        port = server.port
        assert port is not None
        assert port > 0
        assert server.web_url == f"http://127.0.0.1:{port}/static/"
        assert _get(port, f"127.0.0.1:{port}") == 200
        assert _get(port, f"localhost:{port}") == 200
        assert _get(port, f"evil.example:{port}") == 403
        assert _get(port, f"127.0.0.1:{port + 1}") == 403
        assert _get(port, f"evil.example:{port}", "/") == 403  # the websocket route too


@pytest.mark.parametrize("port", [-1, 65536, 10**9])
def test_bad_port_is_a_clear_error(port):
    with pytest.raises(ServerError, match="0..65535"):
        find_free_port(port)


class _GoneTab:
    """A browser websocket whose tab has closed: writing raises, or fails later."""

    def __init__(self, late: bool) -> None:
        self.late = late
        self.writes = 0

    def write_message(self, data, binary=False):
        import asyncio

        import tornado.websocket

        self.writes += 1
        if not self.late:
            raise tornado.websocket.WebSocketClosedError()
        future = asyncio.get_event_loop().create_future()
        future.set_exception(tornado.websocket.WebSocketClosedError())
        return future


def test_closed_browser_tab_is_dropped_without_traceback():
    """meshcat's bridge raised WebSocketClosedError (a traceback per message) when a tab closed
    while the scene streamed; the bridge now drops the tab and keeps serving the others."""
    import asyncio
    import gc

    import meshcat
    import meshcat.geometry as mg

    from ident.viz.recorder import SceneRecorder

    recorder = SceneRecorder()
    vis = meshcat.Visualizer(window=recorder)
    for k in range(3):
        vis[f"box_{k}"].set_object(mg.Box([0.1, 0.1, 0.1]))
    with LoopbackMeshcatServer(port=0) as server:
        server.push(recorder)
        bridge = server._bridge
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        try:
            gone, late = _GoneTab(late=False), _GoneTab(late=True)
            bridge.websocket_pool.update({gone, late})
            bridge.forward_to_websockets([b"set_object", b"/x", recorder.commands[0].data])
            loop.run_until_complete(asyncio.sleep(0))  # the late failure's callback runs
            assert gone not in bridge.websocket_pool
            assert late not in bridge.websocket_pool
            other = _GoneTab(late=False)
            bridge.send_scene(other)  # a tab that closes while its scene is sent
            assert other.writes >= 1
        finally:
            asyncio.set_event_loop(None)
            loop.close()
        gc.collect()  # an unretrieved future exception would be logged here
