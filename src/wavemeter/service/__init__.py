"""The live instrument: ``wavemeter serve`` as a library, and its clients.

:class:`Server` owns the meter (a calibration and its sources), publishes every reading to
many subscribers (ZeroMQ), answers control requests, logs to Parquet and serves metrics and
a live dashboard over HTTP; :class:`Client` and :class:`AsyncClient` read and control it;
:func:`read_log` reads a log folder back. This is the only package that imports pyzmq,
aiohttp and prometheus_client; the names below load on first use. The user guide's page
on the service (``docs/user-guide/service.rst``) describes the wire format and the sockets.
"""

from __future__ import annotations

import importlib

#: public name -> module that defines it
_WHERE = {
    "Server": "server",
    "Client": "client",
    "AsyncClient": "client",
    "ServiceError": "client",
    "Reading": "records",
    "ReadingBatch": "records",
    "ChannelProcessor": "channels",
    "read_log": "parquet_log",
    "VERSION": "encoding",
    "decode_message": "encoding",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
