"""Channels: one laser on the switch each, with its topic, sequence, status and statistics.

A :class:`Channel` turns a block of its raw readings into a :class:`ReadingBatch`: the
calibration's numbers, the next sequence numbers, the service time, the fields a source
adds (``temperature_k`` where the calibration uses it, ``true_frequency_hz`` when
simulated), and the fields of its processors. A processor (:class:`ChannelProcessor`, a lock
for instance) sees every batch of its channel before it is published and may add fields to
it; it is told when the channel's status changes.

Status: ``waiting`` before the first reading, ``ok``, and ``no signal`` when no reading came
within the signal timeout (set by :meth:`Channel.watch`), back to ``ok`` at the next one.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Protocol

import numpy as np

from ..calibration import ReadingFlag
from .blocks import RowBlock
from .readout import CalibrationReader
from .records import Reading, ReadingBatch

__all__ = ["Channel", "ChannelProcessor", "WAITING", "OK", "NO_SIGNAL"]

WAITING = "waiting"
OK = "ok"
NO_SIGNAL = "no signal"
_BITS = [(flag.name, int(flag)) for flag in ReadingFlag]


class ChannelProcessor(Protocol):
    """What a channel's processor (a lock) provides.

    Attributes
    ----------
    outputs : mapping of str to str
        The fields it adds to every batch, name -> unit.
    """

    outputs: Mapping[str, str]

    def observe(self, channel: Channel, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """See a batch's fields (every reading, in order) before it is published; return
        the fields to add, each (N,)."""

    def status_changed(self, channel: Channel, status: str) -> None:
        """The channel's status became ``status`` (``ok``, ``no signal``)."""


class Channel:
    """One channel of the service.

    Parameters
    ----------
    index : int
        The channel number (switch input), >= 0.
    name : str, optional
        A name for people (default ``ch<index>``).
    """

    def __init__(self, index: int, name: str | None = None):
        self.index = index
        self.name = name or f"ch{index}"
        self.status = WAITING
        self.processors: list[ChannelProcessor] = []
        self.next_sequence = 0
        self.readings = 0
        self.flagged = 0
        self.flag_counts = dict.fromkeys((name for name, _ in _BITS), 0)
        self.dropped = 0
        self._last_batch: ReadingBatch | None = None  # its last reading: latest
        self._latest: Reading | None = None
        self.rate_hz = 0.0
        self.last_seen = None  # time.monotonic() of the latest reading
        self._counted = (time.monotonic(), 0)

    def process(self, block: RowBlock, reader: CalibrationReader, run: str) -> ReadingBatch:
        """Read a block of this channel's readings out and number them (counted by
        :meth:`account` once published).

        Parameters
        ----------
        block : RowBlock
            Raw readings of this channel, in order.
        reader : CalibrationReader
            The calibration in force.
        run : str
            The service run, carried by the batch.
        """
        rows = len(block)
        valid = ~block.invalid
        if valid.all():
            frequency, std, flags, extras = reader.read(
                block.powers_w, block.temperature_k, block.coarse_hz
            )
        else:
            frequency, std, flags, extras = reader.unread(rows)
        if valid.any() and not valid.all():
            found = reader.read(
                block.powers_w[valid],
                None if block.temperature_k is None else block.temperature_k[valid],
                None if block.coarse_hz is None else block.coarse_hz[valid],
            )
            frequency[valid], std[valid], flags[valid] = found[:3]
            for name, values in found[3].items():
                extras[name][valid] = values
        columns = {
            "sequence": np.arange(self.next_sequence, self.next_sequence + rows, dtype=np.int64),
            "source_time_ns": block.source_time_ns,
            "time_ns": np.full(rows, time.time_ns(), dtype=np.int64),
            "frequency_hz": frequency,
            "frequency_std_hz": std,
            "flags": flags,
            **extras,
        }
        if reader.uses_temperature:
            temperature = block.temperature_k
            columns["temperature_k"] = np.full(rows, np.nan) if temperature is None else temperature
        if block.true_frequency_hz is not None:
            columns["true_frequency_hz"] = block.true_frequency_hz
        for processor in self.processors:
            columns.update(processor.observe(self, columns))
        self.next_sequence += rows
        return ReadingBatch(self.index, columns, run=run, name=self.name)

    def account(self, batch: ReadingBatch) -> None:
        """Count a published batch in the statistics, and keep its last reading."""
        self._last_batch, self._latest = batch, None
        flags = batch.columns["flags"]
        self.readings += len(flags)
        self.last_seen = time.monotonic()
        flagged = flags != 0
        if flagged.any():
            self.flagged += int(flagged.sum())
            for name, bit in _BITS:
                self.flag_counts[name] += int(np.count_nonzero(flags & bit))

    @property
    def latest(self) -> Reading | None:
        """The latest reading published (None before the first), made when asked."""
        if self._latest is None and self._last_batch is not None:
            self._latest = self._last_batch.last()
        return self._latest

    def watch(self, timeout_s: float, now: float) -> bool:
        """Update the status and the rate at monotonic time ``now``; True when the status
        changed."""
        start, readings = self._counted
        if now - start >= 1.0:
            self.rate_hz = (self.readings - readings) / (now - start)
            self._counted = (now, self.readings)
        if self.last_seen is None:
            status = WAITING
        else:
            status = OK if now - self.last_seen <= timeout_s else NO_SIGNAL
        if status == self.status:
            return False
        self.status = status
        for processor in self.processors:
            processor.status_changed(self, status)
        return True

    def describe(self) -> dict:
        """Status and statistics, JSON-ready."""
        return {
            "channel": self.index,
            "name": self.name,
            "status": self.status,
            "readings": self.readings,
            "next_sequence": self.next_sequence,
            "rate_hz": self.rate_hz,
            "flagged": self.flagged,
            "flag_counts": {name: count for name, count in self.flag_counts.items() if count},
            "dropped": self.dropped,
            "latest": None if self.latest is None else _json_ready(self.latest.as_dict()),
        }


def _json_ready(values: dict) -> dict:
    """NaN and inf as None (JSON has neither)."""
    return {
        name: (None if isinstance(value, float) and not np.isfinite(value) else value)
        for name, value in values.items()
    }
