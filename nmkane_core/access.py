"""Who may reach a server: the Host allow-list rule and access tokens, for every face.

The REST service (``backend.guard``) and the web app's server (``web.server``) hold
requests to the same rule; it lives here, below both, because they do not import each
other.  Standard library only: no web framework is loaded by ``import nmkane_core``.

* **Host allow-list** (DNS rebinding: a page on ``evil.example`` that resolves to 127.0.0.1
  sends ``Host: evil.example``): a request is answered when its ``Host`` header names an
  allowed name — the loopback names, the bound address, names added with ``--allow-host`` —
  or is an IP address (a browser that addresses a server by IP involves no DNS, so no
  rebinding).  Names are compared without the port, in lower case.
* **Tokens**: :func:`new_token` makes one (192 random bits); :func:`token_matches` compares
  a given one with the expected one in constant time.
"""

from __future__ import annotations

import ipaddress
import secrets
from collections.abc import Iterable
from dataclasses import dataclass

__all__ = [
    "LOOPBACK_NAMES",
    "WILDCARD_ADDRESSES",
    "HostAllowList",
    "allowed_host_names",
    "host_name",
    "is_ip",
    "is_loopback",
    "new_token",
    "token_matches",
]

#: always allowed in a ``Host`` header
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
#: bind addresses that mean "every interface" (not a name a client uses)
WILDCARD_ADDRESSES = ("0.0.0.0", "::", "")


def host_name(value: str) -> str:
    """The name in a ``Host`` header (or an address), without the port, in lower case:
    ``Lab.Example:8000`` → ``lab.example``, ``[::1]:8000`` → ``::1``, ``::1`` → ``::1``."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[1 : value.find("]")] if "]" in value else value
    if value.count(":") == 1:
        return value.split(":", 1)[0]
    return value


def is_ip(name: str) -> bool:
    """``name`` (from :func:`host_name`) is an IPv4 or IPv6 address."""
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def is_loopback(host: str) -> bool:
    """True for a loopback address or ``localhost`` (what a server may bind without a token)."""
    host = host.strip("[]").lower()
    if host == "localhost" or host.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def allowed_host_names(bound: str | None = None, extra: Iterable[str] = ()) -> tuple[str, ...]:
    """The loopback names, the bound address (unless a wildcard) and the ``extra`` names, each
    as :func:`host_name` writes it (a port or brackets given with a name are dropped)."""
    names = list(LOOPBACK_NAMES)
    if bound is not None and bound.strip() not in WILDCARD_ADDRESSES:
        names.append(host_name(bound))
    names += [host_name(n) for n in extra if n.strip()]
    return tuple(dict.fromkeys(names))


@dataclass(frozen=True)
class HostAllowList:
    """The rule: a ``Host`` header is answered when its name is in ``names`` or is an IP address."""

    names: frozenset[str]

    @classmethod
    def of(cls, bound: str | None = None, extra: Iterable[str] = ()) -> HostAllowList:
        """The allow-list of a server bound to ``bound`` that also answers to ``extra`` names."""
        return cls(frozenset(allowed_host_names(bound, extra)))

    def admits(self, host_header: str) -> bool:
        """The request with this ``Host`` header value is answered."""
        name = host_name(host_header)
        return name in self.names or is_ip(name)


def new_token() -> str:
    """A fresh access token: 192 random bits, URL-safe."""
    return secrets.token_urlsafe(24)


def token_matches(given: str | None, expected: str) -> bool:
    """``given`` is the ``expected`` token (compared in constant time; None never matches)."""
    if given is None:
        return False
    return secrets.compare_digest(given.encode("utf-8", "surrogatepass"), expected.encode("utf-8", "surrogatepass"))
