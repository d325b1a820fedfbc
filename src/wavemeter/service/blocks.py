"""A block of raw readings on their way from a source to the channels.

Sources (lines, the simulated meter, :meth:`Server.feed <wavemeter.service.Server.feed>`)
make :class:`RowBlock` s; the server splits them by channel and reads them out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RowBlock"]


@dataclass
class RowBlock:
    """Consecutive raw readings, in the order the source took them.

    Attributes
    ----------
    channel : ndarray of int64, shape (N,)
        The channel of each reading.
    powers_w : ndarray, shape (N, ports)
        Port powers (W, or the calibration's relative unit); NaN rows for invalid ones.
    invalid : ndarray of bool, shape (N,)
        Readings that are no reading (a malformed line, NaN, no light): published as NaN
        with the ``INVALID`` flag without reaching the calibration.
    source_time_ns : ndarray of int64, shape (N,)
        When the source took each reading (ns since the epoch).
    temperature_k, coarse_hz : ndarray, shape (N,), optional
        Per-reading inputs (K, Hz), where the source has them.
    true_frequency_hz : ndarray, shape (N,), optional
        The laser's true frequency (Hz): a simulated source knows it.
    arrived : float
        ``time.perf_counter()`` when the block reached the server (its latency's start).
    """

    channel: np.ndarray
    powers_w: np.ndarray
    invalid: np.ndarray
    source_time_ns: np.ndarray
    temperature_k: np.ndarray | None = None
    coarse_hz: np.ndarray | None = None
    true_frequency_hz: np.ndarray | None = None
    arrived: float = 0.0

    @classmethod
    def concat(cls, blocks: list[RowBlock]) -> RowBlock:
        """Blocks one after the other as one (an input some lack is NaN there); the
        earliest arrival is kept."""
        if len(blocks) == 1:
            return blocks[0]

        def joined(name):
            parts = [getattr(b, name) for b in blocks]
            if all(part is None for part in parts):
                return None
            return np.concatenate(
                [
                    np.full(len(b), np.nan) if p is None else p
                    for b, p in zip(blocks, parts, strict=True)
                ]
            )

        return cls(
            channel=np.concatenate([b.channel for b in blocks]),
            powers_w=np.concatenate([b.powers_w for b in blocks]),
            invalid=np.concatenate([b.invalid for b in blocks]),
            source_time_ns=np.concatenate([b.source_time_ns for b in blocks]),
            temperature_k=joined("temperature_k"),
            coarse_hz=joined("coarse_hz"),
            true_frequency_hz=joined("true_frequency_hz"),
            arrived=min(b.arrived for b in blocks),
        )

    def __len__(self) -> int:
        return len(self.channel)

    def take(self, rows: np.ndarray) -> RowBlock:
        """The readings at ``rows`` (indices or a mask), in order."""

        def pick(values):
            return None if values is None else values[rows]

        return RowBlock(
            channel=self.channel[rows],
            powers_w=self.powers_w[rows],
            invalid=self.invalid[rows],
            source_time_ns=self.source_time_ns[rows],
            temperature_k=pick(self.temperature_k),
            coarse_hz=pick(self.coarse_hz),
            true_frequency_hz=pick(self.true_frequency_hz),
            arrived=self.arrived,
        )

    def by_channel(self):
        """``(channel, block)`` for each channel in the block, readings in order."""
        first = self.channel[0]
        if first == self.channel[-1] and (self.channel == first).all():
            yield int(first), self
            return
        for channel in np.unique(self.channel):
            yield int(channel), self.take(self.channel == channel)
