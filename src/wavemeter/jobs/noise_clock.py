"""The sampling rate of a record from its time column, checked chunk by chunk.

The time column's unit comes from its name (``time_s``, ``t_ms``, ``'Time (us)'``; a name
without one is in seconds: :func:`time_unit_s`). Its steps are checked chunk by chunk
against the median step of the first chunk (:class:`Clock`: a gap, a step over
``GAP_FACTOR`` times it, or a relative deviation over ``TIME_JITTER_TOLERANCE`` is an
error naming the row), and the rate is the mean step's inverse, ``(N - 1) / (t_last -
t_first)``: the average rate the analysis assumes (with every step within 1e-3 of the
median, the two agree to that). Given both a rate and a time column,
:func:`~wavemeter.jobs.noise.measure_series` requires them to agree within
``TIME_JITTER_TOLERANCE``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..io.columns import split_unit
from ..units import TIME_UNITS, seconds_per_unit

__all__ = ["TIME_JITTER_TOLERANCE", "GAP_FACTOR", "time_unit_s", "Clock"]

#: largest relative deviation of a time step from the median step (also: of a given rate
#: from the time column's)
TIME_JITTER_TOLERANCE = 1e-3
#: a time step over this many median steps is a gap in the record
GAP_FACTOR = 1.5
#: examples of time column names with their unit, for messages
_TIME_NAMES = "time_s, t_ms, 'Time (us)'"


def time_unit_s(column: str) -> float:
    """Seconds per unit of a time column, from its name: ``time_s``, ``t_ms``, ``'Time
    (us)'``; a name without a time unit is in seconds.

    Raises
    ------
    InputError
        When the name has a bracketed unit that is not a time unit (s, ms, us, ns).
    """
    readings = split_unit(column)
    for _, unit in readings:
        if unit is None:
            continue
        scale = seconds_per_unit(unit)
        if scale is not None:
            return scale
        if len(readings) == 1:  # a bracketed unit must be a time unit
            raise InputError(
                f"time column {column!r}: unknown time unit {unit!r}; units: "
                f"{', '.join(TIME_UNITS)} (e.g. {_TIME_NAMES})",
                parameter="time_column",
            )
    return 1.0


class Clock:
    """The time stamps of a record, checked chunk by chunk for uniform sampling."""

    def __init__(self, column: str, source: Path):
        self.column = column
        self.source = source
        self.scale_s = time_unit_s(column)
        self.first_s: float | None = None
        self.last_s: float | None = None
        self.last_label = ""
        self.step_s: float | None = None
        self.count = 0

    def add(self, table) -> None:
        values = table.kept[self.column]
        if values.dtype.kind not in "fiu":
            raise InputError(
                f"{self.source}: time column {self.column!r} holds text; give the time of "
                f"each reading as a number in seconds (or with its unit in the name: "
                f"{_TIME_NAMES})",
                parameter="time_column",
            )
        times_s = np.asarray(values, dtype=float) * self.scale_s
        if times_s.size == 0:
            return
        bad = np.flatnonzero(~np.isfinite(times_s))
        if bad.size:
            raise InputError(
                f"{self.source}: time column {self.column!r} has no time at "
                f"{table.row_label(int(table.row_index[bad[0]]))} ({values[bad[0]]}); "
                "every reading needs its time stamp: fill it in, or delete the row and split "
                "the record there",
                parameter="time_column",
            )
        if self.first_s is None:
            self.first_s = float(times_s[0])
        joined = times_s if self.last_s is None else np.concatenate(([self.last_s], times_s))
        steps = np.diff(joined)
        if self.step_s is None and steps.size:
            self.step_s = float(np.median(steps))
        if steps.size:
            self._check(steps, table, offset=0 if self.last_s is None else 1)
        self.last_s = float(times_s[-1])
        self.last_label = table.row_label(int(table.row_index[-1]))
        self.count += times_s.size

    def _label(self, table, step: int, offset: int) -> tuple[str, str]:
        """Names of the rows after and before time step ``step`` of a chunk."""
        after = table.row_label(int(table.row_index[step + 1 - offset]))
        before = (
            self.last_label
            if step - offset < 0
            else table.row_label(int(table.row_index[step - offset]))
        )
        return after, before

    def _check(self, steps: np.ndarray, table, offset: int) -> None:
        median = self.step_s
        backwards = np.flatnonzero(steps <= 0)
        if backwards.size:
            first = int(backwards[0])
            after, before = self._label(table, first, offset)
            raise InputError(
                f"{self.source}: time column {self.column!r} does not increase at {after} "
                f"(step {steps[first]:.6g} s after {before}); the readings must be in time "
                "order, each at its own time: sort the file by time or remove repeated rows",
                parameter="time_column",
            )
        gaps = np.flatnonzero(steps > GAP_FACTOR * median)
        if gaps.size:
            after, before = self._label(table, int(gaps[0]), offset)
            raise InputError(
                f"{self.source}: gap in time column {self.column!r} between {before} and "
                f"{after}: {steps[gaps[0]]:.6g} s, {steps[gaps[0]] / median:.3g} times the "
                f"median step {median:.6g} s ({gaps.size} such gap(s) in this part of the "
                "file); a noise analysis needs uniform sampling: split the record at the "
                "gap and analyse the parts, or resample it onto uniform time stamps",
                parameter="time_column",
            )
        deviation = np.abs(steps - median) / median
        jitter = np.flatnonzero(deviation > TIME_JITTER_TOLERANCE)
        if jitter.size:
            worst = int(jitter[np.argmax(deviation[jitter])])
            after, _ = self._label(table, int(jitter[0]), offset)
            raise InputError(
                f"{self.source}: time column {self.column!r} is not uniformly sampled: the "
                f"step before {after} is {steps[jitter[0]]:.6g} s, the median step "
                f"{median:.6g} s, a relative deviation of {deviation[jitter[0]]:.3g} (largest "
                f"{deviation[worst]:.3g}) above the {TIME_JITTER_TOLERANCE:g} allowed; "
                "resample the record onto uniform time stamps, or give the nominal rate "
                "(rate_hz) without the time column if the sampling clock is uniform",
                parameter="time_column",
            )

    def rate_hz(self) -> float:
        """``(N - 1) / (t_last - t_first)`` (Hz): the mean step's inverse."""
        if self.count < 2:
            raise InputError(
                f"{self.source}: time column {self.column!r} has {self.count} time stamp(s); "
                "a rate needs at least two",
                parameter="time_column",
            )
        return (self.count - 1) / (self.last_s - self.first_s)
