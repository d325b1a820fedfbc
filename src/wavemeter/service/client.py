"""Clients of a service: :class:`Client` (blocking) and :class:`AsyncClient` (asyncio).

Both subscribe on the publish socket (a DEALER that sends ``wavemeter.subscribe``) and ask
the control socket (JSON requests); both lock, unlock and ask for the status of a channel's
lock, as ``owner`` (a name unique to the client unless given), and keep their locks alive
(:mod:`.keepalive`) so that the service holds them if the client goes silent. They rejoin a
restarted service by themselves: the service sends a heartbeat every 0.25 s, and a client
that hears nothing for :data:`SILENCE_S` subscribes again (ZeroMQ reconnects the socket
underneath). A restart shows as a new ``run`` and sequences from 0 again (counted in
``restarts``); readings lost to a full queue show as gaps in the sequence (counted in
``missed``).
"""

from __future__ import annotations

import json
import os
import secrets
import socket as sockets
import time

import zmq
import zmq.asyncio

from ..exceptions import WavemeterError
from .addresses import DEFAULT_CONTROL, DEFAULT_PUBLISH
from .encoding import (
    READINGS_FORMAT,
    SUBSCRIBE_FORMAT,
    channel_topic,
    decode_message,
    encode_message,
    encode_request,
)
from .keepalive import AsyncKeepAlive, KeepAlive
from .records import ReadingBatch

__all__ = ["Client", "AsyncClient", "ServiceError", "SILENCE_S", "RECEIVE_BUFFER_BYTES"]

#: seconds without any message after which a client subscribes again
SILENCE_S = 0.75
#: the kernel's receive buffer of the data socket (bytes), fixed rather than grown up to
#: tens of MB by the kernel: a client that stalls is then seen by the service in seconds
RECEIVE_BUFFER_BYTES = 256 * 1024


class ServiceError(WavemeterError):
    """The service refused a request or a subscription; the message says why."""


def _owner_name() -> str:
    """A name unique to a client: host, process and a random part."""
    return f"{sockets.gethostname()}:{os.getpid()}:{secrets.token_hex(3)}"


def _lock_request(channel, setpoint_hz, scan, owner, options) -> dict:
    """The arguments of a ``lock`` request."""
    if scan is not None and not isinstance(scan, dict):
        scan = scan.describe()  # a Scan
    arguments = {"channel": channel, "owner": owner, **options}
    if setpoint_hz is not None:
        arguments["setpoint_hz"] = setpoint_hz
    if scan is not None:
        arguments["scan"] = scan
    if arguments.get("output_limits_v") is not None:
        arguments["output_limits_v"] = list(arguments["output_limits_v"])
    return {k: v for k, v in arguments.items() if v is not None or k == "owner_timeout_s"}


class _Locks:
    """The lock requests both clients share (``request`` sync or async)."""

    def lock(
        self,
        channel: int,
        setpoint_hz: float | None = None,
        *,
        scan=None,
        capture_range_hz: float = 3e9,
        bandwidth_hz: float | None = None,
        actuator_hz_per_v: float | None = None,
        response_s: float | None = None,
        kp_v_per_hz: float | None = None,
        ki_v_per_hz_s: float | None = None,
        kd_v_s_per_hz: float | None = None,
        average: int = 1,
        output_limits_v=None,
        rail_s: float = 1.0,
        owner_timeout_s: float | None = 30.0,
        take_over: bool = False,
    ):
        """Lock ``channel`` to ``setpoint_hz`` (Hz) or to a ``scan``; the lock's status.

        Parameters
        ----------
        channel : int
            A channel with an output.
        setpoint_hz : float, optional
            The frequency to hold (Hz).
        scan : Scan or dict, optional
            A scan instead: ``center_hz``, ``amplitude_hz``, ``period_s``, ``shape``
            (``"triangle"`` or ``"ramp"``).
        capture_range_hz : float
            An error beyond it unlocks the channel with an alarm (Hz).
        bandwidth_hz : float, optional
            The loop bandwidth (Hz; default 1 Hz when no gains are given), with
            ``actuator_hz_per_v`` (the laser's tuning, Hz/V) and ``response_s`` (the
            actuator's time constant, s) where the output does not know them.
        kp_v_per_hz, ki_v_per_hz_s, kd_v_s_per_hz : float, optional
            Explicit gains instead of a bandwidth (V/Hz, V/(Hz s), V s/Hz).
        average : int
            Readings averaged per update.
        output_limits_v : (float, float), optional
            The output's range (V), within the output's own (its own by default).
        rail_s : float
            Seconds at a limit before the railing alarm.
        owner_timeout_s : float or None
            Seconds of silence after which the service holds the lock (this client keeps
            it alive meanwhile); None: never.
        take_over : bool
            Take the lock over from another owner.

        Returns
        -------
        dict
            The status (:meth:`lock_status`).

        Raises
        ------
        ServiceError
            When the service refuses (another owner's lock, a bad setting; nothing changed).
        """
        options = {
            "capture_range_hz": capture_range_hz,
            "bandwidth_hz": bandwidth_hz,
            "actuator_hz_per_v": actuator_hz_per_v,
            "response_s": response_s,
            "kp_v_per_hz": kp_v_per_hz,
            "ki_v_per_hz_s": ki_v_per_hz_s,
            "kd_v_s_per_hz": kd_v_s_per_hz,
            "average": average,
            "output_limits_v": output_limits_v,
            "rail_s": rail_s,
            "owner_timeout_s": owner_timeout_s,
            "take_over": take_over,
        }
        arguments = _lock_request(channel, setpoint_hz, scan, self.owner, options)
        return self._locked(self.request("lock", **arguments), owner_timeout_s)

    def unlock(self, channel: int, *, take_over: bool = False):
        """Unlock ``channel`` (its output stays where it is); the lock's status."""
        return self.request("unlock", channel=channel, owner=self.owner, take_over=take_over)

    def lock_status(self, channel: int | None = None):
        """The lock of ``channel`` (every lock for None): a mapping with ``state``
        (``"locked"``, ``"unlocked"``, ``"holding"``), ``output_v``, ``error_hz``,
        ``error_mean_hz``, ``setpoint_hz``, ``owner``, ``alarms`` (name -> message),
        ``alarm_counts``, ``held_readings``, ``settings`` and more."""
        return self.request("lock_status", channel=channel)


class _Tracker:
    """Sequence bookkeeping shared by both clients."""

    def __init__(self, token, channel):
        self.token = token
        self.topics = ["ch/"] if channel is None else [channel_topic(channel).decode()]
        self.run = None
        self.expected: dict[int, int] = {}
        self.missed = 0
        self.restarts = 0
        self.heard = time.monotonic()

    def subscription(self) -> bytes:
        return encode_message(SUBSCRIBE_FORMAT, topics=self.topics, token=self.token)

    def take(self, frames) -> ReadingBatch | None:
        """A readings batch from a message (None for other messages); raises ServiceError
        for a refused subscription."""
        self.heard = time.monotonic()
        if len(frames) != 2:
            return None
        kind, message = decode_message(frames[1])
        if kind == SUBSCRIBE_FORMAT and not message.get("ok", False):
            raise ServiceError(message.get("error", "subscription refused"))
        if kind != READINGS_FORMAT:
            return None
        batch = message
        if batch.run != self.run:
            if self.run is not None:
                self.restarts += 1
            self.run = batch.run
            self.expected.clear()
        first = int(batch.columns["sequence"][0])
        expected = self.expected.get(batch.channel)
        if expected is not None and first > expected:
            self.missed += first - expected
        self.expected[batch.channel] = first + len(batch)
        return batch


class Client(_Locks):
    """A blocking client of ``wavemeter serve``.

    Parameters
    ----------
    publish, control : str
        The service's publish and control addresses.
    token : str, optional
        The service's token, if it has one.
    timeout_s : float
        Seconds a control request waits for its reply.
    receive_buffer_bytes : int
        The kernel's receive buffer of the data socket; raise it for a far service (more
        than the rate times the round trip).
    owner : str, optional
        The name its locks are owned under (default: host, process and a random part).

    Attributes
    ----------
    missed : int
        Readings lost (gaps in the sequences) since the first.
    restarts : int
        Times the service restarted while reading.
    """

    def __init__(
        self,
        publish=DEFAULT_PUBLISH,
        control=DEFAULT_CONTROL,
        token=None,
        *,
        timeout_s: float = 5.0,
        receive_buffer_bytes: int = RECEIVE_BUFFER_BYTES,
        owner: str | None = None,
    ):
        self.owner = owner or _owner_name()
        self._keepalive = None
        self.publish = publish
        self.control = control
        self.token = token
        self.timeout_s = timeout_s
        self.receive_buffer_bytes = receive_buffer_bytes
        self._context = zmq.Context()
        self._data = None
        self._request_socket = None
        self._tracker = None

    @property
    def missed(self) -> int:
        return 0 if self._tracker is None else self._tracker.missed

    @property
    def restarts(self) -> int:
        return 0 if self._tracker is None else self._tracker.restarts

    def batches(self, channel: int | None = None, timeout_s: float | None = None):
        """Batches of readings as they are published (:class:`ReadingBatch`, columns of
        arrays: the fast way at high rates). The subscription is sent at the call; the
        iterator yields what is published once the service has it.

        Raises
        ------
        TimeoutError
            When no reading came for ``timeout_s`` seconds (None: wait for ever).
        ServiceError
            When the service refuses the subscription (a missing or wrong token).
        """
        return self._batches(self._subscribe(channel), timeout_s)

    def _batches(self, tracker: _Tracker, timeout_s: float | None):
        # a receive that waits at most wait_s (RCVTIMEO): no poll before each message
        wait_s = SILENCE_S if timeout_s is None else min(SILENCE_S, timeout_s)
        self._data.setsockopt(zmq.RCVTIMEO, max(1, round(wait_s * 1000)))
        last = time.monotonic()
        while True:
            try:
                frames = self._data.recv_multipart()
            except zmq.Again:
                frames = None
            if frames is not None:
                batch = tracker.take(frames)
                if batch is not None:
                    last = time.monotonic()
                    yield batch
                    continue
            if timeout_s is not None and time.monotonic() - last >= timeout_s:
                raise TimeoutError(f"no reading from {self.publish} for {timeout_s} s")
            if time.monotonic() - tracker.heard >= SILENCE_S:
                self._send_subscription(tracker)

    def readings(self, channel: int | None = None, timeout_s: float | None = None):
        """Readings one at a time (:class:`Reading`, fields as attributes), as published.

        Parameters
        ----------
        channel : int, optional
            Only this channel's; None: every channel's.
        timeout_s : float, optional
            Raise TimeoutError when no reading came for this long.
        """
        return (
            reading for batch in self.batches(channel, timeout_s) for reading in batch.readings()
        )

    def _subscribe(self, channel) -> _Tracker:
        if self._data is not None:
            self._data.close(linger=0)
        self._data = self._context.socket(zmq.DEALER)
        self._data.setsockopt(zmq.LINGER, 0)
        self._data.setsockopt(zmq.IMMEDIATE, 1)
        self._data.setsockopt(zmq.RCVHWM, 100_000)
        self._data.setsockopt(zmq.RCVBUF, self.receive_buffer_bytes)
        self._data.setsockopt(zmq.RECONNECT_IVL, 100)
        self._data.setsockopt(zmq.RECONNECT_IVL_MAX, 1000)
        self._data.connect(self.publish)
        self._tracker = _Tracker(self.token, channel)
        self._data.poll(self.timeout_s * 1000, zmq.POLLOUT)  # connected (or not running)
        self._send_subscription(self._tracker)
        return self._tracker

    def _send_subscription(self, tracker: _Tracker) -> None:
        tracker.heard = time.monotonic()
        try:
            self._data.send(tracker.subscription(), flags=zmq.DONTWAIT)
        except zmq.Again:  # not connected yet: the next silence tries again
            pass

    def request(self, name: str, **arguments):
        """Send a control request; return its result.

        Raises
        ------
        ServiceError
            With the service's error message (nothing changed).
        TimeoutError
            When no reply came in ``timeout_s`` (the service is down or busy).
        """
        if self._request_socket is None:
            self._request_socket = self._context.socket(zmq.REQ)
            self._request_socket.setsockopt(zmq.LINGER, 0)
            self._request_socket.connect(self.control)
        socket = self._request_socket
        socket.send(encode_request(name, self.token, **arguments))
        if not socket.poll(self.timeout_s * 1000):
            socket.close(linger=0)  # a REQ socket without its reply cannot send again
            self._request_socket = None
            raise TimeoutError(f"no reply from {self.control} in {self.timeout_s} s")
        return _result(socket.recv())

    def status(self) -> dict:
        """The service's status."""
        return self.request("status")

    def latest(self, channel: int) -> dict | None:
        """The latest reading of a channel, as a dict (None before the first)."""
        return self.request("latest", channel=channel)

    def _locked(self, status: dict, timeout_s) -> dict:
        if timeout_s is not None:
            if self._keepalive is None:
                self._keepalive = KeepAlive(self._context, self.control, self.token, self.owner)
            self._keepalive.every(timeout_s)
        return status

    def close(self) -> None:
        """Close the sockets (its locks are no longer kept alive)."""
        if self._keepalive is not None:
            self._keepalive.stop()
            self._keepalive = None
        for socket in (self._data, self._request_socket):
            if socket is not None:
                socket.close(linger=0)
        self._data = self._request_socket = None
        self._context.term()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _result(body: bytes):
    reply = json.loads(body.decode())
    if not reply.get("ok"):
        raise ServiceError(reply.get("error", "the service refused the request"))
    return reply.get("result")


class AsyncClient(_Locks):
    """The asyncio twin of :class:`Client`: ``async for reading in client.readings()``,
    ``await client.request(name, **arguments)``, ``await client.status()``, ``await
    client.lock(...)`` (its locks kept alive by a task)."""

    def __init__(
        self,
        publish=DEFAULT_PUBLISH,
        control=DEFAULT_CONTROL,
        token=None,
        *,
        timeout_s: float = 5.0,
        owner: str | None = None,
    ):
        self.owner = owner or _owner_name()
        self._keepalive = None
        self.publish = publish
        self.control = control
        self.token = token
        self.timeout_s = timeout_s
        self._context = zmq.asyncio.Context()
        self._sockets = []

    async def batches(self, channel: int | None = None, timeout_s: float | None = None):
        """Batches of readings as published; see :meth:`Client.batches`."""
        data = self._socket(zmq.DEALER, self.publish, receive_buffer=True)
        data.setsockopt(zmq.IMMEDIATE, 1)
        tracker = _Tracker(self.token, channel)
        last = time.monotonic()
        await data.send(tracker.subscription())
        while True:
            wait_s = SILENCE_S if timeout_s is None else min(SILENCE_S, timeout_s)
            if await data.poll(wait_s * 1000):
                batch = tracker.take(await data.recv_multipart())
                if batch is not None:
                    last = time.monotonic()
                    yield batch
                    continue
            if timeout_s is not None and time.monotonic() - last >= timeout_s:
                raise TimeoutError(f"no reading from {self.publish} for {timeout_s} s")
            if time.monotonic() - tracker.heard >= SILENCE_S:
                tracker.heard = time.monotonic()
                try:
                    await data.send(tracker.subscription(), flags=zmq.DONTWAIT)
                except zmq.Again:
                    pass

    async def readings(self, channel: int | None = None, timeout_s: float | None = None):
        """Readings one at a time, as published; see :meth:`Client.readings`."""
        async for batch in self.batches(channel, timeout_s):
            for reading in batch.readings():
                yield reading

    async def request(self, name: str, **arguments):
        """Send a control request; return its result (see :meth:`Client.request`)."""
        socket = self._socket(zmq.REQ, self.control)
        try:
            await socket.send(encode_request(name, self.token, **arguments))
            if not await socket.poll(self.timeout_s * 1000):
                raise TimeoutError(f"no reply from {self.control} in {self.timeout_s} s")
            return _result(await socket.recv())
        finally:
            socket.close(linger=0)
            self._sockets.remove(socket)

    async def status(self) -> dict:
        return await self.request("status")

    async def latest(self, channel: int) -> dict | None:
        return await self.request("latest", channel=channel)

    async def _locked(self, status, timeout_s) -> dict:
        status = await status
        if timeout_s is not None:
            if self._keepalive is None:
                self._keepalive = AsyncKeepAlive(self.request, self.owner)
            self._keepalive.every(timeout_s)
        return status

    def _socket(self, kind, address, receive_buffer=False):
        socket = self._context.socket(kind)
        socket.setsockopt(zmq.LINGER, 0)
        if receive_buffer:
            socket.setsockopt(zmq.RCVBUF, RECEIVE_BUFFER_BYTES)
        socket.connect(address)
        self._sockets.append(socket)
        return socket

    def close(self) -> None:
        if self._keepalive is not None:
            self._keepalive.stop()
            self._keepalive = None
        for socket in self._sockets:
            socket.close(linger=0)
        self._sockets.clear()
        self._context.term()
