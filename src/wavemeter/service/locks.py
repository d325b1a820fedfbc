"""The service's locks: one per channel with an output, owned by the client that set it.

A :class:`ChannelLock` is a channel's processor (:class:`~.channels.ChannelProcessor`): it
runs the channel's :class:`~.lock_loop.LockLoop` on every reading before it is published,
adds the lock's fields to it (``lock_state``, ``lock_setpoint_hz``, ``lock_error_hz``,
``lock_output_v``), writes the output to the channel's sink once per batch it changed on,
and holds while the channel has no signal (until its next reading). A :class:`LockManager`
keeps the locks of a server: it checks a lock request, enforces ownership (another client
changes a lock only by taking it over explicitly; an owner silent for its timeout releases
the lock to hold, not to zero) and answers for the status and the dashboard. The control
requests that reach it are in :mod:`.lock_requests`.
"""

from __future__ import annotations

import math
import sys
import time
import traceback

import numpy as np

from ..exceptions import InputError
from .channels import NO_SIGNAL, OK
from .lock_loop import (
    NO_SIGNAL as NO_SIGNAL_ALARM,
)
from .lock_loop import (
    OUTPUT_FAILED,
    OWNER_SILENT,
    STATE_CODES,
    UNLOCKED,
    LockLoop,
    LockSettings,
)
from .outputs import check_sink

__all__ = ["ChannelLock", "LockManager", "LOCK_FIELDS", "DEFAULT_OWNER_TIMEOUT_S"]

#: the fields a lock adds to its channel's readings, name -> unit
LOCK_FIELDS = {
    "lock_state": "0 unlocked, 1 locked, 2 holding",
    "lock_setpoint_hz": "Hz",
    "lock_error_hz": "Hz",
    "lock_output_v": "V",
}
#: seconds an owner may stay silent before its lock holds, unless the request says otherwise
DEFAULT_OWNER_TIMEOUT_S = 30.0


class ChannelLock:
    """The lock of one channel.

    Parameters
    ----------
    channel : int
        The channel.
    sink : OutputSink
        Where its output goes.
    sink_name : str
        What the sink is (shown in status).
    """

    outputs = LOCK_FIELDS

    def __init__(self, channel: int, sink, sink_name: str):
        self.channel = channel
        self.sink = sink
        self.sink_name = sink_name
        self.loop: LockLoop | None = None
        self.owner: str | None = None
        self.owner_timeout_s: float | None = None
        self.owner_seen = time.monotonic()
        self.written_v = float(sink.output_v)
        self.write_errors = 0
        self.origin_ns = None  # the source time the loop's times count from

    # ------------------------------------------------------------------ the processor
    def observe(self, channel, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        loop = self.loop
        if NO_SIGNAL_ALARM in loop.holds:  # readings again: the signal is back
            loop.release(NO_SIGNAL_ALARM)
        stamps = columns["source_time_ns"]
        if self.origin_ns is None:
            self.origin_ns = int(stamps[0])
        times = (stamps - self.origin_ns) * 1e-9  # seconds from the first, to the ns
        frequency = columns["frequency_hz"]
        flags = columns["flags"]
        rows = len(frequency)
        state = np.empty(rows)
        setpoint = np.empty(rows)
        error = np.empty(rows)
        output = np.empty(rows)
        step, codes = loop.step, STATE_CODES
        for k in range(rows):
            output[k] = step(float(times[k]), float(frequency[k]), int(flags[k]))
            state[k] = codes[loop.state]
            setpoint[k] = loop.setpoint_hz
            error[k] = loop.reading_error_hz
        if loop.output_v != self.written_v or OUTPUT_FAILED in loop.holds:
            self._write(loop.output_v)
        return {
            "lock_state": state,
            "lock_setpoint_hz": setpoint,
            "lock_error_hz": error,
            "lock_output_v": output,
        }

    def status_changed(self, channel, status: str) -> None:
        if status == NO_SIGNAL:
            self.loop.hold(
                NO_SIGNAL_ALARM, f"channel {self.channel} has no signal: holding the output"
            )
        elif status == OK:
            self.loop.release(NO_SIGNAL_ALARM)

    def _write(self, voltage_v: float) -> None:
        try:
            self.sink.write(voltage_v)
        except Exception as exc:  # a plug-in's failure must not stop the service: alarm, hold
            self.write_errors += 1
            if self.write_errors == 1:
                traceback.print_exc(file=sys.stderr)
            self.loop.hold(OUTPUT_FAILED, f"writing {voltage_v:.6g} V failed: {exc}")
            return
        self.written_v = voltage_v
        self.loop.release(OUTPUT_FAILED)

    # ------------------------------------------------------------------ views
    def describe(self, now: float | None = None) -> dict:
        """The lock's status, JSON-ready."""
        now = time.monotonic() if now is None else now
        loop = self.loop
        low, high = self.sink.limits_v
        status = {
            "channel": self.channel,
            "state": UNLOCKED if loop is None else loop.state,
            "owner": self.owner,
            "owner_timeout_s": self.owner_timeout_s,
            "owner_silent_s": now - self.owner_seen if self.owner else None,
            "output_v": self.written_v if loop is None else loop.output_v,
            "output_limits_v": [low, high] if loop is None else list(loop.settings.output_limits_v),
            "sink": self.sink_name,
            "setpoint_hz": None,
            "error_hz": None,
            "error_mean_hz": None,
            "held_readings": 0,
            "updates": 0,
            "alarms": {},
            "alarm_counts": {},
            "settings": None,
        }
        if loop is not None:
            status.update(
                setpoint_hz=_finite(loop.setpoint_hz),
                error_hz=_finite(loop.error_hz),
                error_mean_hz=_finite(loop.error_mean_hz),
                held_readings=loop.held,
                updates=loop.updates,
                alarms=dict(loop.alarms),
                alarm_counts=dict(loop.alarm_counts),
                settings=loop.settings.describe(),
            )
        return status


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


class LockManager:
    """The locks of a service.

    Parameters
    ----------
    server : Server
        The service (its channels get the locks' processors).
    sinks : mapping of int to (sink, name)
        Each lockable channel's output sink and what it is.
    """

    def __init__(self, server, sinks: dict):
        self.server = server
        self.locks = {
            int(channel): ChannelLock(int(channel), check_sink(sink, f"the output of {name}"), name)
            for channel, (sink, name) in sinks.items()
        }

    def get(self, channel) -> ChannelLock:
        """The lock of ``channel``.

        Raises
        ------
        InputError
            For a channel without an output.
        """
        lock = self.locks.get(channel) if isinstance(channel, int) else None
        if lock is None:
            known = ", ".join(str(c) for c in sorted(self.locks)) or "none"
            raise InputError(
                f"channel {channel!r} has no output to lock with; channels with an output: {known}",
                parameter="channel",
            )
        return lock

    def check_owner(self, lock: ChannelLock, owner, take_over: bool) -> str:
        """The owner's name, once it may change ``lock``.

        Raises
        ------
        InputError
            For a missing owner, or a lock of another owner not taken over.
        """
        if not isinstance(owner, str) or not owner.strip() or len(owner) > 128:
            raise InputError("owner must be a name of 1 to 128 characters", parameter="owner")
        if not isinstance(take_over, bool):
            raise InputError("take_over must be true or false", parameter="take_over")
        if lock.owner not in (None, owner) and not take_over:
            raise InputError(
                f"channel {lock.channel} is locked by {lock.owner!r}: it stays theirs unless "
                "you take it over explicitly (take_over=True)",
                parameter="owner",
            )
        return owner

    def lock(self, channel, owner, settings: LockSettings, *, take_over=False, timeout_s=None):
        """Engage (or re-set) the lock of ``channel`` for ``owner``; its status."""
        lock = self.get(channel)
        owner = self.check_owner(lock, owner, take_over)
        rate = self.server.channel(channel).rate_hz
        if lock.loop is None:
            lock.loop = LockLoop(
                settings, lock.written_v, interval_s=1.0 / rate if rate > 0 else None
            )
            self.server.channel(channel).processors.append(lock)
        lock.loop.engage(settings)
        if self.server.channel(channel).status == NO_SIGNAL:
            lock.status_changed(None, NO_SIGNAL)
        lock.owner, lock.owner_timeout_s = owner, timeout_s
        lock.owner_seen = time.monotonic()
        return lock.describe()

    def unlock(self, channel, owner, *, take_over=False) -> dict:
        """Unlock ``channel`` (its output stays); the lock is free after."""
        lock = self.get(channel)
        self.check_owner(lock, owner, take_over)
        if lock.loop is not None:
            lock.loop.disengage()
            lock.loop.release(OWNER_SILENT)
        lock.owner = None
        return lock.describe()

    def keepalive(self, owner) -> list[int]:
        """Note that ``owner`` is alive; the channels it owns."""
        now = time.monotonic()
        owned = [c for c, lock in sorted(self.locks.items()) if lock.owner == owner]
        for channel in owned:
            self.locks[channel].owner_seen = now
        return owned

    def watch(self, now: float) -> None:
        """Release the locks of owners silent for their timeout, to hold (monotonic ``now``)."""
        for lock in self.locks.values():
            timeout = lock.owner_timeout_s
            if lock.owner is None or timeout is None or now - lock.owner_seen <= timeout:
                continue
            if lock.loop is not None and lock.loop.engaged:
                lock.loop.hold(
                    OWNER_SILENT,
                    f"owner {lock.owner!r} silent for {now - lock.owner_seen:.3g} s (timeout "
                    f"{timeout:g} s): holding at {lock.loop.output_v:.6g} V until locked again",
                )
            lock.owner = None

    def summary(self) -> list[dict]:
        """Every lock's status."""
        now = time.monotonic()
        return [lock.describe(now) for _, lock in sorted(self.locks.items())]

    def view(self, channel: int) -> dict | None:
        """What the dashboard shows of a channel's lock (None: no output)."""
        lock = self.locks.get(channel)
        if lock is None:
            return None
        status = lock.describe()
        return {
            name: status[name]
            for name in ("state", "owner", "output_v", "setpoint_hz", "error_mean_hz", "alarms")
        }

    def close(self) -> None:
        """Close the sinks that can be closed."""
        for lock in self.locks.values():
            close = getattr(lock.sink, "close", None)
            if close is not None:
                try:
                    close()
                except Exception:  # a plug-in's failure to close: reported, the others close
                    traceback.print_exc(file=sys.stderr)
