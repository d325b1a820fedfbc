"""The plain PUB socket (``--pub``): the publish socket's messages for any ZeroMQ SUB socket.

Beside the ROUTER of :mod:`.publisher` (which :class:`~wavemeter.service.Client` uses and
which counts every loss per subscriber), a service may bind a ZeroMQ PUB socket that carries
the same two-frame messages on the same topics (``ch/<N>/``, ``status/``, ``heartbeat/``):
a SUB socket in any language subscribes with a topic prefix and decodes the documented
msgpack bodies. ZeroMQ keeps a queue of ``hwm`` messages per subscriber and drops the
messages of a subscriber whose queue is full (a stopped or slow one) without waiting, so
it slows neither the service nor the others; those drops are not reported by ZeroMQ, so
the service cannot count them: the subscriber sees them as gaps in ``sequence``. With a
token, a subscriber must log in with ZeroMQ's PLAIN mechanism (user :data:`PLAIN_USER`,
password the token), checked by pyzmq's authenticator.
"""

from __future__ import annotations

import zmq

from .publisher import DEFAULT_HWM, SEND_BUFFER_BYTES, bind

__all__ = ["PlainPublisher", "PLAIN_USER"]

#: the PLAIN user name of a subscriber of a service with a token
PLAIN_USER = "wavemeter"
#: messages above this many bytes are sent without copying
_COPY_BYTES = 65536


class PlainPublisher:
    """A PUB socket that sends every message it is given to the SUB sockets that want it.

    Parameters
    ----------
    context : zmq.asyncio.Context
        The service's ZeroMQ context.
    endpoint : str
        Where to bind (``tcp://127.0.0.1:5562``; port 0 picks a free one).
    token : str, optional
        Subscribers must log in with it (PLAIN, user :data:`PLAIN_USER`).
    hwm : int
        Messages queued per subscriber before its messages are dropped.
    """

    def __init__(self, context, endpoint: str, *, token=None, hwm=DEFAULT_HWM):
        self._authenticator = None
        self.socket = context.socket(zmq.PUB)
        self.socket.setsockopt(zmq.SNDHWM, hwm)
        self.socket.setsockopt(zmq.SNDBUF, SEND_BUFFER_BYTES)
        self.socket.setsockopt(zmq.LINGER, 0)
        if token is not None:
            from zmq.auth.asyncio import AsyncioAuthenticator

            self._authenticator = AsyncioAuthenticator(context)
            self._authenticator.start()
            self._authenticator.configure_plain(domain="*", passwords={PLAIN_USER: token})
            self.socket.plain_server = True
        try:
            bind(self.socket, endpoint, "pub")
        except BaseException:
            if self._authenticator is not None:
                self._authenticator.stop()
            raise
        self.address = self.socket.getsockopt_string(zmq.LAST_ENDPOINT)
        self._send = zmq.Socket.shadow(self.socket.underlying).send_multipart
        self.sent_messages = 0

    def send(self, topic: bytes, body: bytes) -> None:
        """Send one message; ZeroMQ drops it for each subscriber whose queue is full."""
        self._send([topic, body], flags=zmq.DONTWAIT, copy=len(body) < _COPY_BYTES)
        self.sent_messages += 1

    def close(self) -> None:
        self.socket.close(linger=0)
        if self._authenticator is not None:
            self._authenticator.stop()
