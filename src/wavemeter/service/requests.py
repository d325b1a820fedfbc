"""The control requests of a service: status, channels, latest readings, the calibration,
reload and channel names (:meth:`Control.register <wavemeter.service.control.Control.register>`
adds more). Every handler checks its arguments before it changes anything.
"""

from __future__ import annotations

import asyncio
import time

from .._version import __version__
from ..calibration import load_calibration
from ..exceptions import InputError
from .lines import MAX_CHANNELS

__all__ = ["register_requests", "status_of", "MAX_NAME_LENGTH"]

MAX_NAME_LENGTH = 64


def status_of(server) -> dict:
    """The service's status, JSON-ready."""
    totals = server.line_totals
    lines = {"lines": totals.lines, "invalid": totals.invalid, "unroutable": totals.unroutable}
    reasons = dict(totals.reasons)
    for parser in server.line_parsers():
        counts = parser.counts
        lines = {
            "lines": lines["lines"] + counts.lines,
            "invalid": lines["invalid"] + counts.invalid,
            "unroutable": lines["unroutable"] + counts.unroutable,
        }
        for reason, count in counts.reasons.items():
            reasons[reason] = reasons.get(reason, 0) + count
    publisher = server.publisher
    return {
        "service": "wavemeter",
        "version": __version__,
        "run": server.run_id,
        "uptime_s": time.time() - server.started,
        "addresses": server.addresses,
        "calibration": {
            "method": server.calibration.method,
            "label": server.calibration.method_label,
            "path": server.calibration_path,
        },
        "channels": [c.describe() for _, c in sorted(server.channels.items())],
        "sources": [{"name": s.name, "state": s.state} for s in server.sources],
        "lines": {**lines, "reasons": reasons},
        "subscribers": [s.describe() for s in publisher.subscribers.values()],
        "dropped_messages": publisher.dropped_messages,
        "refused_subscriptions": publisher.refused,
        "log": None
        if server.log is None
        else {"folder": str(server.log.folder), "rows": server.log.rows, "error": server.log.error},
        "control": {"requests": server.control.requests, "errors": server.control.errors},
    }


def register_requests(server) -> None:
    """Register the built-in requests on ``server.control``."""
    control = server.control

    def status():
        return status_of(server)

    def channels():
        return server.channel_list()

    def latest(channel: int | None = None):
        if channel is None:
            return {str(index): _latest(c) for index, c in sorted(server.channels.items())}
        return _latest(_known(server, channel))

    def calibration():
        cal = server.calibration
        return {
            "method": cal.method,
            "label": cal.method_label,
            "path": server.calibration_path,
            "ports": list(cal.port_names_),
            "requires": sorted(cal.requires),
            "reading_outputs": dict(cal.reading_outputs),
            "summary": cal.summary().as_dict(),
        }

    async def reload(path: str):
        if not isinstance(path, str) or not path:
            raise InputError("reload needs the path of a calibration file")
        loop = asyncio.get_running_loop()
        try:
            new = await loop.run_in_executor(None, load_calibration, path)
        except OSError as exc:
            raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
        if list(new.port_names_) and len(new.port_names_) != len(server.calibration.port_names_):
            raise InputError(
                f"{path} reads {len(new.port_names_)} ports, the service's sources give "
                f"{len(server.calibration.port_names_)}; the calibration in force is kept"
            )
        for parser in server.line_parsers():
            if parser.header is not None:
                parser.check(new)
        server.use_calibration(new, path)
        return {"method": new.method, "label": new.method_label, "path": path}

    def channel_names(names: dict | None = None):
        if names is not None:
            if not isinstance(names, dict):
                raise InputError("names must be an object of channel number -> name")
            checked = {}
            for key, name in names.items():
                try:
                    index = int(key)
                except (TypeError, ValueError):
                    index = -1
                if not 0 <= index < MAX_CHANNELS:
                    raise InputError(f"channel {key!r}: expected a number 0 .. {MAX_CHANNELS - 1}")
                if not isinstance(name, str) or not name.strip() or len(name) > MAX_NAME_LENGTH:
                    raise InputError(
                        f"name {str(name)[:80]!r} of channel {key}: expected 1 to "
                        f"{MAX_NAME_LENGTH} characters"
                    )
                checked[index] = name.strip()
            for index, name in checked.items():
                server.names[index] = name
                if index in server.channels:
                    server.channels[index].name = name
        known = {i: c.name for i, c in server.channels.items()}
        return {str(i): n for i, n in sorted({**server.names, **known}.items())}

    for name, handler in (
        ("status", status),
        ("channels", channels),
        ("latest", latest),
        ("calibration", calibration),
        ("reload", reload),
        ("channel_names", channel_names),
    ):
        control.register(name, handler)


def _known(server, channel):
    if not isinstance(channel, int) or channel not in server.channels:
        known = ", ".join(str(i) for i in sorted(server.channels)) or "none yet"
        raise InputError(f"no channel {channel!r}; the channels are: {known}")
    return server.channels[channel]


def _latest(channel):
    return None if channel.latest is None else channel.latest.as_dict()
