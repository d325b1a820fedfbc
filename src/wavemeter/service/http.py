"""The HTTP side (aiohttp): ``/metrics`` for Prometheus, ``/`` the live dashboard, its
WebSocket ``/ws``, ``/api/status``, and the dashboard's files from ``static/``.

With a token, every request but those of the page's own files (``/static/``, code and
styles of the package, no data) must carry it (``?token=`` or ``Authorization: Bearer``),
else it gets 401 and nothing. The WebSocket sends a JSON view of every channel every
:data:`PUSH_S` (the trace bins it has not sent yet, so a page holds its history).
"""

from __future__ import annotations

import asyncio
import hmac
import json
from importlib import resources

from aiohttp import WSMsgType, web

from .encoding import json_safe

__all__ = ["make_app", "PUSH_S"]

PUSH_S = 0.25
_TYPES = {".html": "text/html", ".js": "text/javascript", ".css": "text/css"}


def make_app(server) -> web.Application:
    """The aiohttp application of a :class:`~wavemeter.service.server.Server`."""
    token = server.token

    @web.middleware
    async def check_token(request, handler):
        if token is not None and not request.path.startswith("/static/"):
            given = request.query.get("token", "")
            header = request.headers.get("Authorization", "")
            if header.startswith("Bearer "):
                given = header[len("Bearer ") :]
            if not hmac.compare_digest(given.encode(), token.encode()):
                return web.Response(status=401, text="refused: this service needs its token\n")
        return await handler(request)

    async def metrics(request):
        server.update_gauges()
        return web.Response(
            body=server.metrics.text(),
            headers={"Content-Type": "text/plain; version=0.0.4; charset=utf-8"},
        )

    async def status(request):
        return web.json_response(server.status())

    async def index(request):
        return _static_file("index.html")

    async def static(request):
        return _static_file(request.match_info["name"])

    async def websocket(request):
        socket = web.WebSocketResponse(heartbeat=10.0)
        await socket.prepare(request)
        sent: dict[int, int] = {}
        reader = asyncio.ensure_future(_drain(socket))
        try:
            while not socket.closed and not reader.done():
                view = server.dashboard_view(sent)
                for channel in view["channels"]:
                    indices = channel["trace"]["index"]
                    if indices:
                        sent[channel["channel"]] = indices[-1] + 1
                await socket.send_str(json.dumps(json_safe(view), allow_nan=False))
                await asyncio.sleep(PUSH_S)
        except (ConnectionError, RuntimeError):
            pass
        finally:
            reader.cancel()
        return socket

    app = web.Application(middlewares=[check_token])
    app.add_routes(
        [
            web.get("/", index),
            web.get("/metrics", metrics),
            web.get("/api/status", status),
            web.get("/ws", websocket),
            web.get("/static/{name}", static),
        ]
    )
    return app


async def _drain(socket) -> None:
    """Read (and ignore) what the page sends, until it closes."""
    async for message in socket:
        if message.type in (WSMsgType.CLOSE, WSMsgType.ERROR):
            break


def _static_file(name: str) -> web.Response:
    files = resources.files("wavemeter.service") / "static"
    suffix = name[name.rfind(".") :] if "." in name else ""
    if "/" in name or "\\" in name or name.startswith(".") or suffix not in _TYPES:
        raise web.HTTPNotFound()
    path = files / name
    if not path.is_file():
        raise web.HTTPNotFound()
    return web.Response(body=path.read_bytes(), content_type=_TYPES[suffix], charset="utf-8")
