"""The control socket: JSON requests by name, one handler each, token checked first.

The socket is a ZeroMQ ROUTER, so many clients (REQ or DEALER sockets) are served at once. A
request is a JSON object ``{"request": NAME, "token": ..., **arguments}``; the reply is
``{"ok": true, "result": ...}`` or ``{"ok": false, "error": "..."}``. A request that is not
JSON, names no known request, has arguments its handler does not take, lacks the token, or
whose handler raises a :class:`~wavemeter.exceptions.WavemeterError` gets an error reply
naming the problem, and changes nothing (a handler checks before it acts). Handlers are
registered by name (:meth:`Control.register`), so a feature (a lock) adds its own requests.
"""

from __future__ import annotations

import hmac
import inspect
import json
import sys
import traceback
from collections.abc import Callable

import zmq

from ..exceptions import InputError, WavemeterError
from .encoding import decode_json, json_safe
from .publisher import bind

__all__ = ["Control"]


class Control:
    """The control socket of a service.

    Parameters
    ----------
    context : zmq.asyncio.Context
        The service's ZeroMQ context.
    endpoint : str
        Where to bind (``tcp://127.0.0.1:5561``; port 0 picks a free one).
    token : str, optional
        Every request must carry it.
    """

    def __init__(self, context, endpoint: str, *, token: str | None = None):
        self.socket = context.socket(zmq.ROUTER)
        self.socket.setsockopt(zmq.LINGER, 0)
        bind(self.socket, endpoint, "control")
        self.address = self.socket.getsockopt_string(zmq.LAST_ENDPOINT)
        self.token = token
        self.handlers: dict[str, Callable] = {}
        self.requests = 0
        self.errors = 0

    def register(self, name: str, handler: Callable) -> None:
        """Answer requests ``name`` with ``handler(**arguments)`` (a coroutine function or
        a plain one) whose return value, JSON-ready, is the result."""
        if name in self.handlers:
            raise InputError(f"the control request {name!r} is registered already")
        self.handlers[name] = handler

    async def serve(self) -> None:
        """Answer requests until cancelled."""
        while True:
            frames = await self.socket.recv_multipart()
            *envelope, body = frames
            reply = await self.answer(body)
            await self.socket.send_multipart([*envelope, reply])

    async def answer(self, body: bytes) -> bytes:
        """The reply to one request body."""
        self.requests += 1
        try:
            result = await self._call(body)
            reply = {"ok": True, "result": result}
        except WavemeterError as exc:
            self.errors += 1
            reply = {"ok": False, "error": str(exc)}
        except Exception as exc:  # a bug in a handler: reported, and the socket goes on
            self.errors += 1
            traceback.print_exc(file=sys.stderr)
            reply = {"ok": False, "error": f"internal error: {type(exc).__name__}: {exc}"}
        return json.dumps(json_safe(reply)).encode()

    async def _call(self, body: bytes):
        request = decode_json(body)
        token = request.pop("token", None)
        if self.token is not None and not (
            isinstance(token, str) and hmac.compare_digest(token.encode(), self.token.encode())
        ):
            raise InputError("refused: this service needs its token with every request")
        name = request.pop("request", None)
        handler = self.handlers.get(name) if isinstance(name, str) else None
        if handler is None:
            raise InputError(
                f"unknown request {name!r}; known requests: {', '.join(sorted(self.handlers))}"
            )
        try:
            inspect.signature(handler).bind(**request)
        except TypeError as exc:
            raise InputError(f"request {name!r}: {exc}") from None
        result = handler(**request)
        if inspect.isawaitable(result):
            result = await result
        return result

    def close(self) -> None:
        self.socket.close(linger=0)
