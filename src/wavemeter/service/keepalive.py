"""Keeping a client's locks alive: a ``lock_keepalive`` request every quarter of the
shortest owner timeout, from a thread (:class:`KeepAlive`, with a socket of its own) or an
asyncio task (:class:`AsyncKeepAlive`). A client that stops (closed, killed, hung) stops
sending, and the service holds its locks once the timeout has passed.
"""

from __future__ import annotations

import asyncio
import threading

import zmq

from ..exceptions import WavemeterError
from .encoding import encode_request

__all__ = ["KeepAlive", "AsyncKeepAlive", "SHORTEST_PERIOD_S"]

#: the shortest time between two keep-alive requests (s)
SHORTEST_PERIOD_S = 0.05


def _period(timeout_s: float, period_s: float | None) -> float:
    wanted = max(SHORTEST_PERIOD_S, timeout_s / 4.0)
    return wanted if period_s is None else min(period_s, wanted)


class KeepAlive:
    """A thread that tells the service ``owner`` is alive.

    Parameters
    ----------
    context : zmq.Context
        The client's context.
    control : str
        The service's control address.
    token : str or None
        The service's token.
    owner : str
        The owner's name.
    """

    def __init__(self, context, control: str, token, owner: str):
        self.context = context
        self.control = control
        self.token = token
        self.owner = owner
        self.period_s = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="wavemeter-keepalive", daemon=True)
        self._started = False

    def every(self, timeout_s: float) -> None:
        """Keep alive a lock of owner timeout ``timeout_s`` (s) too."""
        self.period_s = _period(timeout_s, self.period_s)
        if not self._started:
            self._started = True
            self._thread.start()

    def _run(self) -> None:
        socket = None
        body = encode_request("lock_keepalive", self.token, owner=self.owner)
        try:
            while not self._stop.wait(self.period_s):
                if socket is None:
                    socket = self.context.socket(zmq.REQ)
                    socket.setsockopt(zmq.LINGER, 0)
                    socket.connect(self.control)
                socket.send(body)
                if socket.poll(self.period_s * 1000):
                    socket.recv()
                else:  # no reply: a REQ socket cannot send again; start a new one
                    socket.close(linger=0)
                    socket = None
        except zmq.ZMQError:  # the context is terminating: the client closed
            pass
        finally:
            if socket is not None:
                socket.close(linger=0)

    def stop(self) -> None:
        """Stop sending (before the client's context is terminated)."""
        self._stop.set()
        if self._started:
            self._thread.join()


class AsyncKeepAlive:
    """An asyncio task that tells the service ``owner`` is alive.

    Parameters
    ----------
    request : coroutine function
        The client's ``request``.
    owner : str
        The owner's name.
    """

    def __init__(self, request, owner: str):
        self.request = request
        self.owner = owner
        self.period_s = None
        self._task = None

    def every(self, timeout_s: float) -> None:
        """Keep alive a lock of owner timeout ``timeout_s`` (s) too."""
        self.period_s = _period(timeout_s, self.period_s)
        if self._task is None:
            self._task = asyncio.ensure_future(self._run())

    async def _run(self) -> None:
        while True:
            await asyncio.sleep(self.period_s)
            try:
                await self.request("lock_keepalive", owner=self.owner)
            except (TimeoutError, OSError, WavemeterError):
                pass  # the service is away or refused: try again next period

    def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            self._task = None
