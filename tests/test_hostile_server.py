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
