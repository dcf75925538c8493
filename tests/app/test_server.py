"""Issue 29: the page's server answers its own page only. Against a real ``fuzzyservo app`` for
every form of ``--host`` (127.0.0.1, localhost, LOCALHOST, 127.0.0.2 and 0.0.0.0 with its
token), a WebSocket opened with a foreign Origin and a request with a foreign Host header
(DNS rebinding) are refused, while the page and its WebSocket, as the page's own script opens
it, still work; the server prints no traceback. The check itself (:class:`Access`) is tested
on its own below, without a server."""

from __future__ import annotations

import http.client
import json
import re
import socket
from collections.abc import Iterator
from dataclasses import dataclass
from urllib.parse import urlsplit

import pytest
import websocket

from fuzzyservo.app.access import Access, Admit, Refuse, access_for
from fuzzyservo.app.page import MAX_UPLOAD_BYTES, upload_name
from fuzzyservo.errors import FuzzyServoError
from fuzzyservo.formats.io import MAX_BYTES
from tests.app.browser import app_server

FOREIGN = "evil.example"


@dataclass
class Reply:
    status: int
    headers: dict[str, str]
    body: str


def get(url: str, *, host: str | None = None, cookie: str | None = None,
        origin: str | None = None) -> Reply:
    """GET ``url`` with the given Host header (default the URL's), Cookie and Origin."""
    u = urlsplit(url)
    assert u.hostname is not None and u.port is not None
    conn = http.client.HTTPConnection(u.hostname, u.port, timeout=120)
    try:
        conn.putrequest("GET", u.path + (f"?{u.query}" if u.query else ""), skip_host=True)
        conn.putheader("Host", host or u.netloc)
        if cookie:
            conn.putheader("Cookie", cookie)
        if origin:
            conn.putheader("Origin", origin)
        conn.endheaders()
        r = conn.getresponse()
        return Reply(r.status, {k.lower(): v for k, v in r.getheaders()},
                     r.read().decode("utf-8", "replace"))
    finally:
        conn.close()


def session_token(page: str) -> str:
    """The Bokeh session token the page's script sends with its WebSocket."""
    m = re.search(r'"token":\s*"([^"]+)"', page)
    assert m, page[:500]
    return m.group(1)


def open_ws(url: str, token: str, *, host: str | None = None, origin: str | None = None,
            cookie: str | None = None) -> websocket.WebSocket:
    """Open the page's WebSocket as its script does (Bokeh's subprotocol and session
    token), with the given Host and Origin (default: the page's own)."""
    u = urlsplit(url)
    return websocket.create_connection(
        f"ws://{u.netloc}/ws", subprotocols=["bokeh", token], host=host or u.netloc,
        origin=origin or f"http://{host or u.netloc}", cookie=cookie, timeout=120)


def refused(url: str, token: str, **kw: str | None) -> int:
    """The HTTP status with which the WebSocket's handshake is refused."""
    with pytest.raises(websocket.WebSocketBadStatusException) as info:
        open_ws(url, token, **kw).close()
    return int(info.value.status_code)


def acknowledged(ws: websocket.WebSocket) -> bool:
    """Whether the server's first message on the WebSocket is Bokeh's ACK (the session is
    open: the page's document follows)."""
    try:
        header = json.loads(ws.recv())
    finally:
        ws.close()
    return bool(header["msgtype"] == "ACK")


@pytest.fixture
def server_log() -> Iterator[list[str]]:
    log: list[str] = []
    yield log
    text = "".join(log)
    assert "Traceback" not in text, text


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost", "LOCALHOST", "127.0.0.2"])
def test_a_loopback_host_refuses_a_foreign_origin_and_host(host: str,
                                                           server_log: list[str]) -> None:
    with app_server("--host", host, log=server_log) as url:
        u = urlsplit(url)
        want = "127.0.0.2" if host == "127.0.0.2" else "127.0.0.1"
        assert u.hostname == want and not u.query  # no token on this machine only
        page = get(url)
        assert page.status == 200 and "Bokeh" in page.body
        token = session_token(page.body)
        # the page's own WebSocket works, under every name of the address served, in any case
        names = [want] + (["localhost", "LOCALHOST", "LocalHost"] if want == "127.0.0.1"
                          else [])
        for name in names:
            assert get(url, host=f"{name}:{u.port}").status == 200
        # (each WebSocket opened makes a session: the page is built on the server)
        assert acknowledged(open_ws(url, token, host=f"{names[-1]}:{u.port}"))
        # another site's page opening the WebSocket (cross-site WebSocket hijacking)
        for origin in (f"http://{FOREIGN}", f"http://{FOREIGN}:{u.port}", "null",
                       f"https://{u.netloc}", f"http://{want}:{u.port + 1}"):
            assert refused(url, token, origin=origin) == 403, origin
        # a name made to point here (DNS rebinding), on the page and on the WebSocket
        for foreign in (f"{FOREIGN}:{u.port}", FOREIGN, f"{want}:{u.port + 1}",
                        f"127.0.0.3:{u.port}", f"0.0.0.0:{u.port}"):
            assert get(url, host=foreign).status == 403, foreign
            assert refused(url, token, host=foreign, origin=f"http://{foreign}") == 403
        # a request with a foreign Origin to the page itself
        assert get(url, origin=f"http://{FOREIGN}").status == 403
        # a WebSocket that does not speak Bokeh's protocol: refused in one line (it was a
        # traceback in the server's log)
        with pytest.raises(websocket.WebSocketBadStatusException) as info:
            websocket.create_connection(f"ws://{u.netloc}/ws", timeout=60)
        assert info.value.status_code == 400
    assert any("refused GET /ws" in line and FOREIGN in line for line in server_log)


def test_every_interface_needs_the_token_and_refuses_a_foreign_origin_and_host(
        server_log: list[str]) -> None:
    with app_server("--host", "0.0.0.0", log=server_log) as url:
        u = urlsplit(url)
        m = re.fullmatch(r"token=([A-Za-z0-9_-]{43})", u.query)
        assert u.hostname == "127.0.0.1" and m, url
        secret = m.group(1)
        bare = f"http://{u.netloc}/"
        # without the token, or with another, nothing is served
        assert get(bare).status == 403
        assert get(f"{bare}?token={'A' * 43}").status == 403
        assert get(bare, cookie=f"fuzzyservo-token-{u.port}={'A' * 43}").status == 403
        # the address printed sets the cookie and loads the page without the token
        first = get(url)
        assert first.status == 302 and first.headers["location"] == "/"
        cookie = first.headers["set-cookie"].split(";")[0]
        assert cookie == f"fuzzyservo-token-{u.port}={secret}"
        assert "HttpOnly" in first.headers["set-cookie"]
        page = get(bare, cookie=cookie)
        assert page.status == 200 and "Bokeh" in page.body
        token = session_token(page.body)
        assert acknowledged(open_ws(bare, token, cookie=cookie))
        assert refused(bare, token) == 403  # the WebSocket needs the token too
        # with the token, still no foreign Origin and no foreign Host
        assert refused(bare, token, cookie=cookie, origin=f"http://{FOREIGN}") == 403
        for foreign in (f"{FOREIGN}:{u.port}", FOREIGN):
            assert get(url, host=foreign).status == 403
            assert get(bare, host=foreign, cookie=cookie).status == 403
            assert refused(bare, token, cookie=cookie, host=foreign,
                           origin=f"http://{foreign}") == 403
    # the addresses other machines may use are printed with the token (when it has any)
    others = [line for line in server_log if line.startswith("fuzzyservo app: from other")]
    if access_for("0.0.0.0", u.port).others:
        assert len(others) == 1 and f"?token={secret}" in others[0], server_log
    else:
        assert others == []


def test_the_page_with_its_token_works_in_the_browser(server_log: list[str]) -> None:
    from tests.app.browser import Page

    with app_server("--host", "0.0.0.0", log=server_log) as url, Page(url) as page:
        assert page.run_number() >= 1 and page.error() is None
        assert "token=" not in page.driver.current_url  # not left in the address bar


# -- the check alone

def headers(host: str, **more: str) -> dict[str, str]:
    return {"Host": host, **more}


def test_a_loopback_form_is_this_machine_only_and_names_what_it_serves() -> None:
    for form in ("127.0.0.1", "localhost", "LOCALHOST", "LocalHost"):
        a = access_for(form, 8000)
        assert a.local and a.token is None
        assert a.hosts() == ["127.0.0.1:8000", "localhost:8000"]
    a = access_for("127.0.0.2", 8000)
    assert a.local and a.hosts() == ["127.0.0.2:8000"]
    assert a.url() == "http://127.0.0.2:8000/"
    wild = access_for("0.0.0.0", 8000)
    assert not wild.local and wild.token is not None and len(wild.token) == 43
    assert access_for("0.0.0.0", 8000).token != wild.token  # a new one each time
    assert wild.token not in repr(wild)  # never in a log line
    assert {"127.0.0.1:8000", "localhost:8000"} <= set(wild.hosts())
    assert wild.url() == f"http://127.0.0.1:8000/?token={wild.token}"
    assert "*" not in "".join(wild.hosts() + a.hosts())


def test_the_check_refuses_a_foreign_host_or_origin_in_any_case() -> None:
    a = access_for("localhost", 8000)
    assert a.check(headers("LOCALHOST:8000"), "/") is None
    assert a.check(headers("127.0.0.1:8000", Origin="HTTP://127.0.0.1:8000"), "/ws") is None
    for bad in ("evil.example:8000", "localhost:8001", "localhost", "localhost.evil:8000",
                "127.0.0.1:8000, evil.example:8000", ""):
        assert isinstance(v := a.check(headers(bad), "/"), Refuse) and v.status == 403, bad
    assert a.check({}, "/") == Refuse(400, "no Host header")
    for origin in ("http://evil.example", "null", "http://localhost:8000",
                   "https://127.0.0.1:8000", "http://127.0.0.1:8000/x"):
        v = a.check(headers("127.0.0.1:8000", Origin=origin), "/ws", websocket=True)
        assert isinstance(v, Refuse) and v.status == 403, origin
    # on port 80 a browser leaves the port out
    assert access_for("127.0.0.1", 80).check(headers("localhost"), "/") is None


def test_the_token_is_required_in_the_query_or_its_cookie() -> None:
    a = Access(host="0.0.0.0", port=8000, names=("127.0.0.1", "example.org"),
               shown="127.0.0.1", token="s3cret")
    h = headers("example.org:8000")
    assert a.check(h, "/") == Refuse(403, "no token: open the address the command printed "
                                          "(with ?token=...)")
    assert a.check(h, "/?token=s3cre") == Refuse(403, "wrong token")
    assert a.check(h, "/?token=s3cret&token=s3cret") == Refuse(403, "wrong token")
    assert a.check(h, "/?token=%C3%A9") == Refuse(403, "wrong token")  # not ASCII
    v = a.check(h, "/?x=1&token=s3cret")
    assert isinstance(v, Admit) and v.location == "/?x=1"
    assert v.cookie == "fuzzyservo-token-8000=s3cret; Path=/; HttpOnly; SameSite=Lax"
    assert isinstance(v := a.check(h, "//evil.example/?token=s3cret"), Admit)
    assert v.location == "/"  # never a redirect to another server
    assert a.check(h, "/ws?token=s3cret", websocket=True) is None
    assert a.check({**h, "Cookie": "fuzzyservo-token-8000=s3cret"}, "/static/x.js") is None
    for jar in ("fuzzyservo-token-8000=s3cre", "fuzzyservo-token-8001=s3cret", "a=\x00;;=",
                "fuzzyservo-token-8000"):
        assert isinstance(a.check({**h, "Cookie": jar}, "/"), Refuse), jar
    # the token does not admit a foreign Host or Origin
    assert isinstance(a.check(headers("evil.example:8000"), "/?token=s3cret"), Refuse)
    assert isinstance(a.check({**h, "Origin": "http://evil.example"}, "/?token=s3cret"),
                      Refuse)


@pytest.mark.parametrize(("form", "needle"), [
    ("", "not an IPv4 address or a host name"),
    (" ", "not an IPv4 address or a host name"),
    ("a b", "not an IPv4 address or a host name"),
    ("999.1.1.1", "not an IPv4 address or a host name"),
    ("127.1", "not an IPv4 address or a host name"),
    ("::1", "an IPv6 address cannot be served"),
    ("[::1]", "an IPv6 address cannot be served"),
])
def test_a_bad_host_is_one_line(form: str, needle: str) -> None:
    with pytest.raises(FuzzyServoError) as info:
        access_for(form, 8000)
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_an_address_of_another_machine_is_one_line_naming_host() -> None:
    from tests.app.test_settings import printed

    # 192.0.2.1 (TEST-NET-1) is no machine's own address: binding it fails before serving
    status, _, err = printed(["app", "--no-browser", "--host", "192.0.2.1", "--port", "8000"])
    lines = err.strip().splitlines()
    assert status == 2 and lines[-1].startswith("fuzzyservo: error: --host 192.0.2.1: not an "
                                                "address of this machine"), err
    assert lines[0].startswith("fuzzyservo: warning: --host 192.0.2.1: the page is served "
                               "to other machines")
    assert len(lines) == 2


def test_an_upload_goes_through_the_readers_limits() -> None:
    assert MAX_UPLOAD_BYTES == MAX_BYTES  # the CLI's readers' limit
    assert upload_name("C.fcl", MAX_BYTES) == "C.fcl"
    assert upload_name("/home/u/My System.fis", 10) == "My System.fis"
    for name, size, needle in (("big.fll", MAX_BYTES + 1, "-byte limit"),
                               ("x.txt", 10, "use .fis, .fcl or .fll"),
                               ("..", 10, "not a file name"), ("", 10, "not a file name"),
                               (None, 10, "not a file name"),
                               ("a\nb.fis", 10, "not a file name")):
        with pytest.raises(FuzzyServoError) as info:
            upload_name(name, size)
        assert needle in str(info.value), name
    # the page's WebSocket takes a file of the limit (in base64), so the reader names it
    from fuzzyservo.app.server import WEBSOCKET_MAX_MESSAGE_BYTES

    assert WEBSOCKET_MAX_MESSAGE_BYTES > 4 * MAX_BYTES / 3 + 100_000


def test_the_free_port_check_binds_what_is_served() -> None:
    # a port taken on 127.0.0.2 is named as the port (not the host)
    from tests.app.test_settings import printed

    with socket.socket() as s:
        s.bind(("127.0.0.2", 0))
        s.listen()
        port = s.getsockname()[1]
        status, _, err = printed(["app", "--no-browser", "--host", "127.0.0.2", "--port",
                                  str(port)])
    assert status == 2
    assert err.strip() == (f"fuzzyservo: error: --port {port}: cannot listen on "
                           f"127.0.0.2:{port} (Address already in use); give another --port")
