"""Addresses the service binds: parsed, and refused where they are not the loopback and no
token guards them."""

from __future__ import annotations

import ipaddress
import re

from ..exceptions import InputError

__all__ = [
    "check_binds",
    "http_host_port",
    "tcp_host_port",
    "is_loopback",
    "DEFAULT_PUBLISH",
    "DEFAULT_CONTROL",
    "DEFAULT_HTTP",
]

DEFAULT_PUBLISH = "tcp://127.0.0.1:5560"
DEFAULT_CONTROL = "tcp://127.0.0.1:5561"
DEFAULT_HTTP = "127.0.0.1:8560"

_TCP = re.compile(r"^tcp://(?P<host>\[[^\]]+\]|[^:/]+):(?P<port>\d+|\*)$")


def is_loopback(host: str) -> bool:
    """Whether ``host`` is this machine only (``127.0.0.0/8``, ``::1``, ``localhost``)."""
    host = host.strip("[]")
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def tcp_host_port(endpoint: str) -> tuple[str, int]:
    """``(host, port)`` of ``tcp://HOST:PORT``.

    Raises
    ------
    InputError
        For anything else.
    """
    match = _TCP.match(endpoint.strip())
    if match is None or match["port"] == "*":
        raise InputError(
            f"address {endpoint!r}: expected tcp://HOST:PORT (e.g. tcp://127.0.0.1:5560)"
        )
    port = int(match["port"])
    if port > 65535:
        raise InputError(f"address {endpoint!r}: port {port} is above 65535")
    return match["host"], port


def http_host_port(address: str) -> tuple[str, int]:
    """``(host, port)`` of ``HOST:PORT`` (or ``http://HOST:PORT``)."""
    address = address.strip().removeprefix("http://").rstrip("/")
    return tcp_host_port(f"tcp://{address}")


def check_binds(endpoints: dict[str, str | None], token: str | None) -> None:
    """Refuse a malformed address, and one other than the loopback without a token.

    Parameters
    ----------
    endpoints : dict of str to str or None
        What binds where: ``tcp://HOST:PORT`` (``http``: ``HOST:PORT``); None: nothing.
    token : str or None
        The service's token.

    Raises
    ------
    InputError
        Naming the address; ``parameter`` is ``"token"`` when a token would allow it.
    """
    for role, endpoint in endpoints.items():
        if endpoint is None:
            continue
        host, _ = http_host_port(endpoint) if role == "http" else tcp_host_port(endpoint)
        if not is_loopback(host) and token is None:
            raise InputError(
                f"the {role} address {endpoint} is reachable from other machines; binding "
                "there needs a token (clients then give it), or bind to 127.0.0.1",
                parameter="token",
            )
