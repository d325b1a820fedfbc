"""The publish socket: every batch of readings to every subscriber that asked for its topic.

The socket is a ZeroMQ ROUTER (a subscriber connects a DEALER and sends a
``wavemeter.subscribe`` message): the service sends each message to each subscriber on its
own, without waiting (``ROUTER_MANDATORY``, ``DONTWAIT``), so one whose queue is full (a
stopped or slow process; the high-water mark is per subscriber) loses that message, counted
against it and the channel, while the others get theirs at once. A subscriber that vanished
is forgotten at the next message to it. Every subscriber gets a heartbeat every
:data:`~wavemeter.service.encoding.HEARTBEAT_S`; it re-subscribes when they stop (a
restarted service), which is how :class:`~wavemeter.service.Client` rejoins by itself.
A plain PUB socket (:mod:`.plain_pub`), where bound, gets every message too.
"""

from __future__ import annotations

import hmac
import time
from dataclasses import dataclass, field

import zmq

from ..exceptions import InputError
from .encoding import (
    HEARTBEAT_FORMAT,
    HEARTBEAT_TOPIC,
    MAX_BATCH,
    STATUS_TOPIC,
    SUBSCRIBE_FORMAT,
    channel_topic,
    decode_message,
    encode_batch,
    encode_message,
)
from .records import ReadingBatch


def bind(socket, endpoint: str, role: str) -> None:
    """Bind a ZeroMQ socket; a failure (the port taken) is an InputError naming it."""
    try:
        socket.bind(endpoint)
    except zmq.ZMQError as exc:
        socket.close(linger=0)
        raise InputError(f"cannot bind the {role} address {endpoint}: {exc}") from None


__all__ = ["Publisher", "Subscriber", "SUBSCRIBED_TOPIC", "DEFAULT_HWM", "SEND_BUFFER_BYTES"]

#: the topic of the reply to a subscription
SUBSCRIBED_TOPIC = b"subscribed/"
#: messages queued per subscriber before its messages are dropped
DEFAULT_HWM = 10000
#: the kernel's send buffer per subscriber (bytes): bounds what a stopped subscriber holds
#: up beside the high-water mark, so that its losses start (and are counted) within seconds
SEND_BUFFER_BYTES = 256 * 1024
#: messages above this many bytes are sent without copying
_COPY_BYTES = 65536


@dataclass
class Subscriber:
    """A connected subscriber: its topics and what it got and lost."""

    identity: bytes
    topics: tuple[bytes, ...]
    since: float = field(default_factory=time.time)
    sent_messages: int = 0
    dropped_messages: int = 0
    dropped_readings: int = 0
    full: bool = False  # its last message was dropped (its queue was full)

    def wants(self, topic: bytes) -> bool:
        return any(topic.startswith(prefix) for prefix in self.topics)

    def describe(self) -> dict:
        return {
            "topics": [topic.decode() for topic in self.topics],
            "since": self.since,
            "sent_messages": self.sent_messages,
            "dropped_messages": self.dropped_messages,
            "dropped_readings": self.dropped_readings,
        }


class Publisher:
    """The publish socket of a service.

    Parameters
    ----------
    context : zmq.asyncio.Context
        The service's ZeroMQ context.
    endpoint : str
        Where to bind (``tcp://127.0.0.1:5560``; port 0 picks a free one).
    token : str, optional
        A subscription must carry it.
    hwm : int
        Messages queued per subscriber before its messages are dropped.
    run : str
        The service run, in heartbeats.
    """

    def __init__(self, context, endpoint: str, *, token=None, hwm=DEFAULT_HWM, run=""):
        self.socket = context.socket(zmq.ROUTER)
        self.socket.setsockopt(zmq.ROUTER_MANDATORY, 1)
        self.socket.setsockopt(zmq.SNDHWM, hwm)
        self.socket.setsockopt(zmq.SNDBUF, SEND_BUFFER_BYTES)
        self.socket.setsockopt(zmq.LINGER, 0)
        bind(self.socket, endpoint, "publish")
        self.address = self.socket.getsockopt_string(zmq.LAST_ENDPOINT)
        self._send = zmq.Socket.shadow(self.socket.underlying).send_multipart
        self.token = token
        self.run = run
        self.subscribers: dict[bytes, Subscriber] = {}
        self.dropped_messages = 0
        self.refused = 0
        self.on_dropped = None  # called with (channel, readings) for each dropped message
        self.plain = None  # a PlainPublisher that gets every message too (--pub)

    def publish(self, batch: ReadingBatch) -> None:
        """Send a batch (split at :data:`MAX_BATCH` readings) to its subscribers."""
        topic = channel_topic(batch.channel)
        # those whose queue was full last time go last: a stopped one delays no other
        wanting = sorted(
            (s for s in self.subscribers.values() if s.wants(topic)), key=lambda s: s.full
        )
        plain = self.plain
        if not wanting and plain is None:
            return
        for start in range(0, len(batch), MAX_BATCH):
            part = batch
            if len(batch) > MAX_BATCH:
                columns = {k: v[start : start + MAX_BATCH] for k, v in batch.columns.items()}
                part = ReadingBatch(batch.channel, columns, run=batch.run, name=batch.name)
            body = encode_batch(part)
            if plain is not None:
                plain.send(topic, body)
            for subscriber in wanting:
                if not self._deliver(subscriber, topic, body):
                    subscriber.dropped_readings += len(part)
                    if self.on_dropped is not None:
                        self.on_dropped(batch.channel, len(part))

    def publish_status(self, channels: list[dict]) -> None:
        """Send every channel's status to every subscriber of ``status/``."""
        body = encode_message("wavemeter.status", run=self.run, channels=channels)
        if self.plain is not None:
            self.plain.send(STATUS_TOPIC, body)
        for subscriber in list(self.subscribers.values()):
            if subscriber.wants(STATUS_TOPIC):
                self._deliver(subscriber, STATUS_TOPIC, body)

    def heartbeat(self) -> None:
        """Send a heartbeat to every subscriber."""
        body = encode_message(HEARTBEAT_FORMAT, run=self.run, time_ns=time.time_ns())
        if self.plain is not None:
            self.plain.send(HEARTBEAT_TOPIC, body)
        for subscriber in list(self.subscribers.values()):
            self._deliver(subscriber, HEARTBEAT_TOPIC, body, count=False)

    def _deliver(self, subscriber: Subscriber, topic: bytes, body: bytes, count=True) -> bool:
        """Send one message without waiting; False when the subscriber's queue was full."""
        try:
            self._send(
                [subscriber.identity, topic, body],
                flags=zmq.DONTWAIT,
                copy=len(body) < _COPY_BYTES,
            )
        except zmq.Again:
            subscriber.full = True
            if count:
                subscriber.dropped_messages += 1
                self.dropped_messages += 1
            return False
        except zmq.ZMQError as exc:
            if exc.errno == zmq.EHOSTUNREACH:  # gone: forget it
                self.subscribers.pop(subscriber.identity, None)
                return True
            raise
        subscriber.sent_messages += 1
        subscriber.full = False
        return True

    async def serve(self) -> None:
        """Take subscriptions until cancelled."""
        while True:
            frames = await self.socket.recv_multipart()
            if len(frames) == 2:
                self._subscribe(*frames)

    def _subscribe(self, identity: bytes, body: bytes) -> None:
        try:
            kind, message = decode_message(body)
            if kind != SUBSCRIBE_FORMAT:
                raise InputError(f"expected a {SUBSCRIBE_FORMAT} message, got {kind}")
            if self.token is not None and not hmac.compare_digest(
                str(message.get("token") or "").encode(), self.token.encode()
            ):
                raise InputError("refused: this service needs its token to subscribe")
            topics = message.get("topics", [""])
            if not isinstance(topics, list) or not all(isinstance(t, str) for t in topics):
                raise InputError("topics must be a list of strings")
        except InputError as exc:
            self.refused += 1
            reply = encode_message(SUBSCRIBE_FORMAT, ok=False, error=str(exc))
            self._deliver(Subscriber(identity, ()), SUBSCRIBED_TOPIC, reply, count=False)
            return
        if message.get("leave"):
            self.subscribers.pop(identity, None)
            return
        wanted = tuple(topic.encode() for topic in topics) + (STATUS_TOPIC,)
        known = self.subscribers.get(identity)
        if known is None:
            self.subscribers[identity] = Subscriber(identity, wanted)
        else:
            known.topics = wanted
        reply = encode_message(SUBSCRIBE_FORMAT, ok=True, run=self.run)
        self._deliver(self.subscribers[identity], SUBSCRIBED_TOPIC, reply, count=False)

    def close(self) -> None:
        self.socket.close(linger=0)
