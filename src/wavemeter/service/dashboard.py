"""What the dashboard shows of a channel: its recent trace and a rolling Allan deviation.

A :class:`Trace` keeps the means of a channel's readable readings over
:data:`BIN_S` bins for the last :data:`TRACE_S` seconds (a few thousand points, whatever
the rate), and from them the overlapping Allan deviation (allantools) of the latest run of
bins without a gap, recomputed at most every :data:`ADEV_EVERY_S`.
"""

from __future__ import annotations

import math
import time
from collections import deque

import allantools
import numpy as np

from ..calibration import ReadingFlag
from .channels import NO_SIGNAL, Channel
from .records import ReadingBatch

__all__ = ["Trace", "BIN_S", "TRACE_S", "ADEV_EVERY_S", "channel_view"]

BIN_S = 0.1
TRACE_S = 300.0
ADEV_EVERY_S = 2.0
#: fewest bins for an Allan deviation
_ADEV_MIN_BINS = 8
_INVALID = int(ReadingFlag.INVALID)


class Trace:
    """A channel's recent history, in bins of :data:`BIN_S` seconds."""

    def __init__(self):
        self.points: deque = deque(maxlen=int(TRACE_S / BIN_S))  # (index, time_s, mean_hz)
        self.count = 0  # bins made so far: the index of the next
        self._bin = None  # (bin number, sum, n)
        self._adev = {"tau_s": [], "adev_hz": []}
        self._adev_at = 0.0

    def add(self, batch: ReadingBatch) -> None:
        """Fold a batch's readable readings into the bins."""
        frequency = batch.columns["frequency_hz"]
        times_ns = batch.columns["source_time_ns"]
        if len(frequency) == 1:  # the common case at a reading per batch, in plain numbers
            value = float(frequency[0])
            if math.isfinite(value) and not int(batch.columns["flags"][0]) & _INVALID:
                self._fold(math.floor(int(times_ns[0]) * 1e-9 / BIN_S), value, 1)
            return
        usable = np.isfinite(frequency) & ((batch.columns["flags"] & ReadingFlag.INVALID) == 0)
        if not usable.any():
            return
        numbers = np.floor(times_ns[usable] * 1e-9 / BIN_S).astype(np.int64)
        values = frequency[usable]
        if numbers[0] == numbers[-1]:
            self._fold(int(numbers[0]), float(values.sum()), len(values))
            return
        for number in np.unique(numbers):
            chosen = values[numbers == number]
            self._fold(int(number), float(chosen.sum()), len(chosen))

    def _fold(self, number: int, total: float, n: int) -> None:
        if self._bin is not None and self._bin[0] == number:
            self._bin = (number, self._bin[1] + total, self._bin[2] + n)
            return
        if self._bin is not None and number > self._bin[0]:
            done, sum_hz, count = self._bin
            self.points.append((self.count, (done + 0.5) * BIN_S, sum_hz / count))
            self.count += 1
        if self._bin is None or number > self._bin[0]:
            self._bin = (number, total, n)

    def since(self, index: int) -> dict:
        """The bins with index >= ``index``: ``{"index": [...], "time_s": [...],
        "frequency_hz": [...]}``."""
        chosen = [point for point in self.points if point[0] >= index]
        return {
            "index": [p[0] for p in chosen],
            "time_s": [p[1] for p in chosen],
            "frequency_hz": [p[2] for p in chosen],
        }

    def adev(self) -> dict:
        """``{"tau_s": [...], "adev_hz": [...]}`` of the latest gap-free run of bins."""
        now = time.monotonic()
        if now - self._adev_at < ADEV_EVERY_S:
            return self._adev
        self._adev_at = now
        times = np.array([p[1] for p in self.points])
        values = np.array([p[2] for p in self.points])
        if len(times) >= 2:
            gaps = np.flatnonzero(np.diff(times) > 1.5 * BIN_S)
            if gaps.size:
                times, values = times[gaps[-1] + 1 :], values[gaps[-1] + 1 :]
        if len(values) < _ADEV_MIN_BINS:
            self._adev = {"tau_s": [], "adev_hz": []}
            return self._adev
        taus, adev, _, _ = allantools.oadev(
            values, rate=1.0 / BIN_S, data_type="freq", taus="octave"
        )
        self._adev = {"tau_s": taus.tolist(), "adev_hz": adev.tolist()}
        return self._adev


def channel_view(channel: Channel, trace: Trace, since: int, *, lock=None, reference=None) -> dict:
    """A channel as the dashboard shows it (JSON-ready): latest values, status, alarms,
    the trace bins from ``since``, the Allan deviation, and its lock's and reference's
    views where it has them (their alarms join the channel's)."""
    latest = channel.latest
    alarms = []
    if channel.status == NO_SIGNAL:
        alarms.append("no signal")
    flags = 0 if latest is None else int(latest.flags)
    if flags:
        names = [flag.name for flag in ReadingFlag if flags & flag]
        alarms.append("latest reading flagged: " + ", ".join(names))
    if channel.dropped:
        alarms.append(f"{channel.dropped} readings dropped to slow subscribers")
    if lock is not None:
        alarms += [f"lock {name}: {message}" for name, message in lock["alarms"].items()]
    if reference is not None and reference["alarm"]:
        alarms.append(f"reference refused: {reference['alarm']}")

    def number(value):
        return None if value is None or value != value else value

    return {
        "channel": channel.index,
        "name": channel.name,
        "status": channel.status,
        "alarms": alarms,
        "frequency_hz": number(None if latest is None else latest.frequency_hz),
        "frequency_std_hz": number(None if latest is None else latest.frequency_std_hz),
        "flags": flags,
        "sequence": None if latest is None else latest.sequence,
        "rate_hz": channel.rate_hz,
        "readings": channel.readings,
        "trace": trace.since(since),
        "adev": trace.adev(),
        "lock": lock,
        "reference": reference,
    }
