"""Unwrapping a frequency series read modulo the FSR, chunk by chunk.

A calibration of one interferometer reads the frequency modulo its FSR (so does a
calibration that picks its window or fringe order from one coarse frequency for the whole
file): the series is unwrapped with period FSR, chunk by chunk, across excluded readings
(:class:`Unwrapper`). A step of more than ``AMBIGUOUS_STEP_FSR`` (a quarter) of the FSR
between consecutive usable readings is ambiguous (the laser moved that far, or the unwrap
added a whole FSR): a :class:`~wavemeter.exceptions.CalibrationWarning` says how many and
where.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import CalibrationWarning
from ..units import frequency_text

__all__ = ["AMBIGUOUS_STEP_FSR", "AMBIGUOUS_STEP_CAUSE", "Unwrapper"]

#: a step between consecutive readings above this fraction of the FSR is ambiguous
AMBIGUOUS_STEP_FSR = 0.25
#: cause of the warning about ambiguous steps
AMBIGUOUS_STEP_CAUSE = "ambiguous_step"


class Unwrapper:
    """Unwraps a frequency series with period FSR, chunk by chunk, across NaN readings,
    and counts the ambiguous steps (over ``AMBIGUOUS_STEP_FSR`` of the FSR)."""

    def __init__(self, fsr_hz: float):
        self.fsr_hz = fsr_hz
        self.last_hz: float | None = None
        self.ambiguous = 0
        self.first: tuple[str, float] | None = None  # row and size of the first ambiguous step

    def __call__(self, frequency_hz: np.ndarray, table) -> None:
        """Unwrap one chunk's frequencies (m,) in place; NaN stay NaN."""
        usable = np.flatnonzero(np.isfinite(frequency_hz))
        if usable.size == 0:
            return
        values = frequency_hz[usable]
        joined = values if self.last_hz is None else np.concatenate(([self.last_hz], values))
        unwrapped = np.unwrap(joined, period=self.fsr_hz)
        steps = np.abs(np.diff(unwrapped))
        ambiguous = np.flatnonzero(steps > AMBIGUOUS_STEP_FSR * self.fsr_hz)
        if ambiguous.size and self.first is None:
            row = usable[ambiguous[0] + (1 if self.last_hz is None else 0)]
            self.first = (table.row_label(int(table.row_index[row])), float(steps[ambiguous[0]]))
        self.ambiguous += ambiguous.size
        unwrapped = unwrapped if self.last_hz is None else unwrapped[1:]
        frequency_hz[usable] = unwrapped
        self.last_hz = float(unwrapped[-1])

    def warning(self, source: Path) -> CalibrationWarning | None:
        if not self.ambiguous:
            return None
        row, step_hz = self.first
        return CalibrationWarning(
            f"{source}: {self.ambiguous} step(s) between consecutive readings exceed "
            f"{AMBIGUOUS_STEP_FSR:g} of the FSR ({frequency_text(self.fsr_hz)}), the first "
            f"before {row} ({frequency_text(step_hz)}): the calibration reads the frequency "
            "modulo its FSR, so the series, unwrapped to the nearest fringe, may be off by "
            "whole FSRs from there on",
            cause=AMBIGUOUS_STEP_CAUSE,
            remedy="read faster than the laser moves a quarter of the FSR, or use a meter "
            "that reads the absolute frequency (a cascade of stages)",
        )
