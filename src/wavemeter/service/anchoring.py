"""The service's reference channel: its readings feed a :class:`~.reference.ReferenceKeeper`,
whose accepted re-anchors become the calibration in force, and whose every attempt is
logged.

:class:`Anchoring` is also the reference channel's processor: it adds ``reference_error_hz``
(reading - known frequency) to the channel's readings. After each block of the reference's
readings it hands the keeper their port readings and values; an accepted re-anchor swaps
the calibration between two blocks (:meth:`Server.anchor
<wavemeter.service.server.Server.anchor>`), so every reading is read by one calibration and
the locks go on through it. Every attempt, accepted or refused, is appended as a JSON line
to ``reanchors.jsonl`` in the log folder (when the service logs), with the offset before and
after; a refusal raises the reference alarm (status, dashboard) until the next accepted one.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from .encoding import json_safe
from .reference import ReferenceKeeper

__all__ = ["Anchoring", "EVENTS_FILE"]

EVENTS_FILE = "reanchors.jsonl"


class Anchoring:
    """A service's reference channel.

    Parameters
    ----------
    server : Server
        The service.
    channel : int
        The channel that sees the reference laser.
    frequency_hz : float
        Its known frequency (Hz).
    **settings
        Of :class:`~.reference.ReferenceKeeper` (``interval_s``, ``window_s``,
        ``threshold_hz``, ``max_drift_hz_per_s``).
    """

    outputs = {"reference_error_hz": "Hz"}

    def __init__(self, server, channel: int, frequency_hz: float, **settings):
        self.server = server
        self.channel = int(channel)
        self.keeper = ReferenceKeeper(server.calibration, frequency_hz, **settings)
        self.path = None

    def start(self, log_folder) -> None:
        """Attach to the channel; log events into ``log_folder`` (None: not at all)."""
        self.server.channel(self.channel).processors.append(self)
        if log_folder is not None:
            self.path = log_folder / EVENTS_FILE

    def observe(self, channel, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {"reference_error_hz": columns["frequency_hz"] - self.keeper.frequency_hz}

    def status_changed(self, channel, status: str) -> None:
        pass

    def take(self, block, batch) -> None:
        """A block of the reference's raw readings and the batch they were read into."""
        columns = batch.columns
        inputs = {
            name: getattr(block, name)
            for name in ("temperature_k", "coarse_hz")
            if getattr(block, name) is not None
        }
        event = self.keeper.add(
            columns["source_time_ns"] * 1e-9,
            block.powers_w,
            columns["frequency_hz"],
            columns["flags"],
            **inputs,
        )
        if event is None:
            return
        if event.accepted:
            self.server.anchor(self.keeper.calibration)
        self._log(event)

    def _log(self, event) -> None:
        if self.path is None:
            return
        record = {"channel": self.channel, "time_ns": time.time_ns(), **event.describe()}
        try:
            with open(self.path, "a", encoding="utf-8") as handle:
                handle.write(json.dumps(json_safe(record)) + "\n")
        except OSError as exc:
            print(f"warning: cannot log the re-anchor to {self.path}: {exc}", file=sys.stderr)
            self.path = None

    def rebase(self, calibration) -> None:
        """A reloaded calibration becomes the keeper's base."""
        self.keeper.rebase(calibration)

    def view(self, channel: int) -> dict | None:
        """What the dashboard shows of ``channel`` as the reference (None: it is not)."""
        if channel != self.channel:
            return None
        keeper = self.keeper
        return {
            "frequency_hz": keeper.frequency_hz,
            "accepted": keeper.accepted,
            "refused": keeper.refused,
            "alarm": keeper.alarm,
        }

    def describe(self) -> dict:
        """The reference's settings, counts, alarm and latest attempt, JSON-ready."""
        return {"channel": self.channel, **self.keeper.describe()}
