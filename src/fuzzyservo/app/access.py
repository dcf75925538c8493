"""Who the page's server answers (docs/app.md, "Who can reach the page").

Every request is checked before Bokeh sees it:

- its ``Host`` header must name the address actually served, with its port, in any case: for
  a loopback address or name, that address, ``localhost`` when 127.0.0.1 is served, and the
  name given; for a wildcard (``0.0.0.0``) also this machine's host names and the IPv4
  addresses of its interfaces. A foreign name is refused (DNS rebinding: a page of another
  site whose name was made to point here sends its own name);
- an ``Origin`` header, when there is one (a browser always sends one with a WebSocket), must
  be the page's own origin, ``http://`` and that Host: another site's page cannot open the
  page's WebSocket (cross-site WebSocket hijacking);
- when other machines are served (an address that is not loopback), a secret token
  (:func:`secrets.token_urlsafe`) must come with it: in the query (``?token=...``, the address
  the command prints) or in the cookie the server sets when the page is opened with it, and
  is compared with :func:`hmac.compare_digest`.

Needs the standard library only (no Panel): the server glue is :mod:`.server`.
"""

from __future__ import annotations

import hmac
import ipaddress
import re
import secrets
import socket
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from http.cookies import SimpleCookie
from urllib.parse import parse_qsl, urlencode, urlsplit

from ..errors import InputError, ParameterError

__all__ = ["Access", "Admit", "Refuse", "access_for", "is_wildcard"]

#: The query parameter that carries the token.
TOKEN_PARAMETER = "token"

#: Addresses that mean every interface of the machine.
WILDCARDS = ("0.0.0.0",)

_NAME = re.compile(r"(?=.{1,253}\Z)[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?"
                   r"(\.[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?)*\.?\Z")
_DOTTED_NUMBERS = re.compile(r"[0-9.]+\Z")


@dataclass(frozen=True, slots=True)
class Refuse:
    """A request refused: the HTTP status and the one line that says why."""

    status: int
    reason: str


@dataclass(frozen=True, slots=True)
class Admit:
    """A page opened with the token in its address: set the cookie and load ``location``
    (the same address without the token, so it is not left in the address bar)."""

    location: str
    cookie: str


def is_wildcard(host: str) -> bool:
    """Whether ``host`` (as given to ``--host``) means every interface."""
    return host in WILDCARDS


@dataclass(frozen=True, slots=True)
class Access:
    """What the server listens on and whom it answers.

    Parameters
    ----------
    host : str
        The address to listen on, as Tornado is given it (lower case).
    port : int
        The TCP port.
    names : tuple of str
        The names and IPv4 addresses (lower case) a request's Host header may carry, each with
        ``:port``; the page's origin is ``http://`` and one of them.
    shown : str
        The name or address of the URL printed (and opened) on this machine.
    others : tuple of str
        The names and addresses other machines may use (a wildcard's; else empty).
    token : str or None
        The token every request must carry; None when only this machine is served.
    """

    host: str
    port: int
    names: tuple[str, ...]
    shown: str
    others: tuple[str, ...] = ()
    token: str | None = field(default=None, repr=False)  # never in a log line

    @property
    def local(self) -> bool:
        """Whether only this machine is served (no token)."""
        return self.token is None

    @property
    def cookie_name(self) -> str:
        """The cookie that carries the token (one per port: cookies ignore ports)."""
        return f"fuzzyservo-token-{self.port}"

    def hosts(self) -> list[str]:
        """The Host headers answered, ``name:port`` (Bokeh's WebSocket origin allowlist)."""
        return [f"{n}:{self.port}" for n in self.names]

    def url(self, name: str | None = None) -> str:
        """The page's address at ``name`` (default :attr:`shown`), with the token if any."""
        query = f"?{urlencode({TOKEN_PARAMETER: self.token})}" if self.token else ""
        return f"http://{name or self.shown}:{self.port}/{query}"

    def check(self, headers: Mapping[str, str], uri: str, *,
              websocket: bool = False) -> Refuse | Admit | None:
        """Check one request; None when it is to be served as it is.

        Parameters
        ----------
        headers : mapping
            The request's headers (case-insensitive lookups, as Tornado's).
        uri : str
            The request's path and query.
        websocket : bool
            Whether it asks for a WebSocket (``Upgrade: websocket``).
        """
        host = headers.get("Host")
        if host is None:
            return Refuse(400, "no Host header")
        allowed = set(self.hosts())
        if self.port == 80:
            allowed |= set(self.names)
        if host.lower() not in allowed:
            return Refuse(403, f"Host {host!r} is not this server's (it answers "
                               f"{', '.join(sorted(allowed))})")
        origin = headers.get("Origin")
        if origin is not None and origin.lower() != f"http://{host.lower()}":
            return Refuse(403, f"Origin {origin!r} is not the page's (http://{host})")
        if self.token is None:
            return None
        parts = urlsplit(uri)
        query = parse_qsl(parts.query, keep_blank_values=True)
        given = [v for k, v in query if k == TOKEN_PARAMETER]
        if given:
            if len(given) != 1 or not _same(given[0], self.token):
                return Refuse(403, "wrong token")
            if websocket or headers.get("Sec-Fetch-Dest", "document") != "document":
                return None
            rest = urlencode([(k, v) for k, v in query if k != TOKEN_PARAMETER])
            # a path of this server only ("//name" would send the browser elsewhere)
            path = parts.path if parts.path.startswith("/") and not parts.path.startswith(
                "//") else "/"
            return Admit(location=path + (f"?{rest}" if rest else ""),
                         cookie=f"{self.cookie_name}={self.token}; Path=/; HttpOnly; "
                                f"SameSite=Lax")
        cookie = _cookie(headers.get("Cookie", ""), self.cookie_name)
        if cookie is None:
            return Refuse(403, "no token: open the address the command printed "
                               "(with ?token=...)")
        if not _same(cookie, self.token):
            return Refuse(403, "wrong token")
        return None


def _same(given: str, token: str) -> bool:
    return hmac.compare_digest(given.encode("utf-8", "replace"), token.encode("ascii"))


def _cookie(header: str, name: str) -> str | None:
    jar: SimpleCookie = SimpleCookie()
    try:
        jar.load(header)
    except Exception:  # a malformed Cookie header: no token
        return None
    morsel = jar.get(name)
    return None if morsel is None else morsel.value


def access_for(host: str, port: int) -> Access:
    """Resolve ``--host`` into the :class:`Access` of the server.

    ``host`` is an IPv4 address, a host name or ``0.0.0.0`` (every interface), in any case. An
    address or name whose every address is loopback (127.0.0.0/8, ``localhost``) serves this
    machine only; any other serves other machines and gets a token.

    Raises
    ------
    ParameterError
        ``host`` is empty, IPv6, or neither an IPv4 address nor a host name.
    InputError
        The name does not resolve.
    """
    h = host.lower()
    if ":" in h:
        raise ParameterError(f"--host {host}: an IPv6 address cannot be served (Bokeh's server "
                             f"checks the page's origin by host:port); give an IPv4 address or "
                             f"a name, e.g. 127.0.0.1")
    literal = _ipv4(h)
    if literal is None and (not _NAME.match(h) or _DOTTED_NUMBERS.match(h)):
        raise ParameterError(f"--host {host!r}: not an IPv4 address or a host name; give e.g. "
                             f"127.0.0.1 (this machine) or 0.0.0.0 (every interface)")
    if is_wildcard(h):
        addresses = _interface_addresses()
        machine = _machine_names()
        others = tuple(sorted(a for a in addresses if not _loopback(a))) + machine
        return Access(host=h, port=port,
                      names=_unique(("localhost", *sorted(addresses), *machine)), shown="127.0.0.1",
                      others=_unique(others), token=secrets.token_urlsafe(32))
    if literal is not None:
        resolved = [literal]
    else:
        try:
            infos = socket.getaddrinfo(h, port, socket.AF_INET, socket.SOCK_STREAM)
        except OSError as exc:
            raise InputError(f"--host {host}: cannot resolve it ({exc.strerror or exc}); give "
                             f"an address of this machine, e.g. 127.0.0.1") from None
        resolved = sorted({str(info[4][0]) for info in infos})
    local = all(_loopback(a) for a in resolved)
    names: list[str] = [*resolved, h]
    if "127.0.0.1" in resolved:
        names.append("localhost")
    return Access(host=h, port=port, names=_unique(names), shown=resolved[0] if local else h,
                  token=None if local else secrets.token_urlsafe(32))


def _unique(items: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(items))


def _ipv4(text: str) -> str | None:
    try:
        return str(ipaddress.IPv4Address(text))
    except ValueError:
        return None


def _loopback(address: str) -> bool:
    return ipaddress.ip_address(address).is_loopback


def _machine_names() -> tuple[str, ...]:
    names = {n.lower() for n in (socket.gethostname(), socket.getfqdn()) if n}
    return tuple(sorted(n for n in names if _NAME.match(n) and n != "localhost"))


def _interface_addresses() -> set[str]:
    """The IPv4 addresses a wildcard serves: loopback, this machine's names' addresses and, on
    Linux, every interface's (elsewhere give ``--host`` the address to serve)."""
    found = {"127.0.0.1"}
    for name in _machine_names():
        try:
            found |= {str(i[4][0]) for i in socket.getaddrinfo(name, None, socket.AF_INET)}
        except OSError:
            pass
    if sys.platform.startswith("linux"):
        import fcntl
        import struct

        siocgifaddr = 0x8915
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for _, ifname in socket.if_nameindex():
                try:
                    packed = fcntl.ioctl(s.fileno(), siocgifaddr,
                                         struct.pack("256s", ifname.encode()[:15]))
                except OSError:  # an interface without an IPv4 address
                    continue
                found.add(socket.inet_ntoa(packed[20:24]))
    return found
