"""A large sweep diagnosed on every k-th reading, its calibration fitted on all of them.

The learned calibration needs every reading only through sums (the binned moments of
:mod:`wavemeter.calibration.models.moments`); its checks and diagnostics need the readings
themselves. On a sweep of more than ``DIAGNOSTIC_SAMPLES`` readings they see every k-th
reading in sweep order (``k`` the smallest power of two that keeps at most
``DIAGNOSTIC_SAMPLES``): the same sample on every run, whether the sweep comes whole or in
chunks of any size (:class:`SweepSample` doubles ``k`` as readings arrive). The fitted map
is evaluated on the sample; nothing is refitted on it. What the sample cannot give (the
span, the extremes of the total power, the spread of the monitor, the largest reading,
:meth:`SweepSample.median_step_hz`) is taken from every reading as it passes, and a sweep
given in chunks is checked chunk by chunk (:class:`CheckedChunks`) as a whole one is.

Theory (why ``2^16`` to ``2^17`` readings suffice): the docs' large-sweeps page
(``docs/theory/large-sweeps.rst``, "Diagnosing a large sweep on a sample").
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError
from ...validation import check_dark, check_frequency, check_monitor, check_powers

__all__ = [
    "CheckedChunks",
    "DIAGNOSTIC_SAMPLES",
    "SweepSample",
    "diagnostic_stride",
    "median_step_hz",
]

#: most readings the checks and diagnostics of a learned calibration see (module text)
DIAGNOSTIC_SAMPLES = 1 << 17


def median_step_hz(frequency_hz: np.ndarray) -> float:
    """Median spacing (Hz) of the distinct sweep frequencies (0 when all are equal).

    A sweep in frequency order (rising or falling: a swept laser) is not sorted: its steps
    are those of the sorted frequencies, up to their order, which the median ignores.
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    steps = np.diff(frequency)
    if np.all(steps <= 0.0):
        steps = -steps
    elif not np.all(steps >= 0.0):
        steps = np.diff(np.sort(frequency))
    steps = steps[steps > 0]
    return float(np.median(steps)) if steps.size else 0.0


def diagnostic_stride(samples: int, limit: int = DIAGNOSTIC_SAMPLES) -> int:
    """The smallest power of two ``k`` with ``ceil(samples / k) <= limit``: every k-th reading
    is diagnosed.

    Parameters
    ----------
    samples : int
        Readings of the sweep.
    limit : int
        Most readings diagnosed, >= 1.

    Returns
    -------
    int
    """
    stride = 1
    while -(-samples // stride) > limit:
        stride *= 2
    return stride


class SweepSample:
    """Every k-th reading of a sweep given in chunks, and what needs every reading.

    Feed validated (dark-subtracted) chunks in sweep order with :meth:`add`; ``stride``
    doubles whenever the readings kept would exceed ``limit``, so that at any time the kept
    readings are those of :func:`diagnostic_stride` for the readings added (the first, the
    ``k+1``-th, ...).

    Parameters
    ----------
    limit : int
        Most readings kept, >= 1.

    Attributes
    ----------
    samples : int
        Readings added.
    stride : int
        ``k``: every k-th reading is kept.
    frequency_hz : ndarray, shape (n,)
        The kept readings' frequencies (Hz).
    powers_w : ndarray, shape (n, ports)
        Their port readings (W).
    monitor_w : ndarray, shape (n,), or None
        Their monitored power (any linear unit), when the sweep has a monitor.
    low_hz, high_hz : float
        Lowest and highest frequency of every reading (Hz).
    total_range_w : (float, float)
        Lowest and highest total power (sum over the ports) of a reading (W).
    largest_w : float
        Largest ``|reading|`` (W).
    """

    def __init__(self, limit: int = DIAGNOSTIC_SAMPLES):
        if limit < 1:
            raise InputError(f"limit must be at least 1, got {limit}", parameter="limit")
        self.limit = int(limit)
        self.samples = 0
        self.stride = 1
        self.low_hz, self.high_hz = np.inf, -np.inf
        self.total_range_w = (np.inf, -np.inf)
        self.largest_w = 0.0
        self._kept: list[tuple] = []  # (frequency, readings, monitor or None, changes)
        self._monitor_moments = (0, 0.0, 0.0)  # count, mean, sum of squared deviations
        self._last_hz: float | None = None
        self._rising = self._falling = False
        self._changes = 0  # steps between readings of different frequency so far

    # ------------------------------------------------------------------ accumulation
    def add(self, frequency_hz: np.ndarray, powers_w: np.ndarray, monitor_w=None) -> None:
        """Add a validated chunk: frequencies (m,) Hz, readings (m, ports) W, monitor (m,)."""
        rows = frequency_hz.shape[0]
        if rows == 0:
            return
        total = self.samples + rows
        while -(-total // self.stride) > self.limit:
            self.stride *= 2
            if self._kept:  # the readings kept are those at multiples of the new stride
                self._kept = [
                    tuple(None if part is None else part[::2].copy() for part in self._arrays())
                ]
        changes = self._add_steps(frequency_hz)
        first = -self.samples % self.stride
        self._kept.append(
            tuple(
                None if part is None else part[first :: self.stride].copy()
                for part in (frequency_hz, powers_w, monitor_w, changes)
            )
        )
        self.samples = total
        self._add_extremes(frequency_hz, powers_w)
        if monitor_w is not None:
            self._add_monitor(monitor_w)

    def _arrays(self) -> tuple:
        """The kept frequencies, readings, monitor (or None) and changes of frequency so far."""
        if len(self._kept) != 1:
            parts = [
                None if part[0] is None else np.concatenate(part)
                for part in zip(*self._kept, strict=True)
            ]
            self._kept = [tuple(parts)]
        return self._kept[0]

    def _add_extremes(self, frequency_hz: np.ndarray, powers_w: np.ndarray) -> None:
        self.low_hz = min(self.low_hz, float(frequency_hz.min()))
        self.high_hz = max(self.high_hz, float(frequency_hz.max()))
        total = powers_w @ np.ones(powers_w.shape[1])
        low, high = self.total_range_w
        self.total_range_w = (min(low, float(total.min())), max(high, float(total.max())))
        self.largest_w = max(self.largest_w, float(powers_w.max()), -float(powers_w.min()))

    def _add_steps(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Whether the sweep stays in frequency order; the changes of frequency from the
        first reading to each of the chunk's (m,)."""
        previous = frequency_hz[:1] if self._last_hz is None else [self._last_hz]
        steps = np.diff(frequency_hz, prepend=previous)
        self._rising = self._rising or bool(np.any(steps > 0))
        self._falling = self._falling or bool(np.any(steps < 0))
        changes = self._changes + np.cumsum(steps != 0)
        self._changes = int(changes[-1])
        self._last_hz = float(frequency_hz[-1])
        return changes

    def _add_monitor(self, monitor_w: np.ndarray) -> None:
        """Mean and spread of the monitor, merged chunk by chunk (Chan et al.)."""
        count, mean, squares = self._monitor_moments
        rows = monitor_w.shape[0]
        chunk_mean = float(monitor_w.mean())
        chunk_squares = float(np.sum((monitor_w - chunk_mean) ** 2))
        total = count + rows
        delta = chunk_mean - mean
        self._monitor_moments = (
            total,
            mean + delta * rows / total,
            squares + chunk_squares + delta**2 * count * rows / total,
        )

    # ------------------------------------------------------------------ results
    @property
    def frequency_hz(self) -> np.ndarray:
        return self._arrays()[0]

    @property
    def powers_w(self) -> np.ndarray:
        return self._arrays()[1]

    @property
    def monitor_w(self) -> np.ndarray | None:
        return self._arrays()[2]

    @property
    def span_hz(self) -> float:
        """Span of every reading (Hz)."""
        return self.high_hz - self.low_hz

    @property
    def monitor_mean_w(self) -> float:
        """Mean monitored power over every reading."""
        return self._monitor_moments[1]

    @property
    def monitor_relative_std(self) -> float:
        """Standard deviation of the monitored power over its mean, every reading."""
        count, mean, squares = self._monitor_moments
        return float(np.sqrt(squares / count)) / mean

    def median_step_hz(self) -> float:
        """The sweep's median step between distinct frequencies (Hz), from the sample.

        For a sweep in frequency order (rising or falling: a swept laser), the median over
        the sample's intervals of their mean step, each interval's step divided by the
        changes of frequency the whole sweep makes in it (counted as the readings pass):
        exact when every reading is kept, and for every k-th reading of evenly spaced
        frequencies, each read once or several times. Otherwise the sample's median step
        (:func:`~wavemeter.calibration.checks.fsr_guard.median_step_hz`) times
        ``(d_s - 1) / (d - 1)``, ``d_s`` the sample's distinct frequencies and
        ``d = N d_s / n`` the sweep's, as readings in random order have them.
        """
        frequency, *_, changes = self._arrays()
        if not (self._rising and self._falling):
            counts = np.diff(changes)
            moved = counts > 0
            if not moved.any():
                return 0.0
            return float(np.median(np.abs(np.diff(frequency))[moved] / counts[moved]))
        step = median_step_hz(frequency)
        if self.stride == 1:
            return step
        kept_distinct = np.unique(frequency).size
        distinct = self.samples * kept_distinct / frequency.size
        return step * (kept_distinct - 1) / max(distinct - 1, 1)


class CheckedChunks:
    """Chunks ``(frequency_hz, powers, power_monitor_w or None)`` of a sweep (as
    :meth:`~wavemeter.calibration.Calibrator.fit_chunks` takes them), each checked as
    ``fit`` checks a sweep and dark-subtracted, empty ones left out; ``dark`` (the checked
    ``dark_w``) once the first chunk gave the port count."""

    def __init__(self, chunks, dark_w):
        self._chunks = chunks
        self._dark_w = dark_w
        self.dark = None
        self._layout: tuple[int, bool] | None = None

    def __iter__(self):
        start = 0
        for index, chunk in enumerate(self._chunks):
            try:
                frequency_hz, powers, monitor_w = chunk
            except (TypeError, ValueError):
                raise InputError(
                    f"chunk {index} must be (frequency_hz, powers, power_monitor_w or None), "
                    f"got {type(chunk).__name__}"
                ) from None
            try:
                readings = check_powers(powers, min_samples=0)
                frequency = check_frequency(frequency_hz, readings.shape[0])
                monitor = check_monitor(monitor_w, readings.shape[0])
                self._check_layout(readings.shape[1], monitor is not None)
            except InputError as exc:
                raise InputError(
                    f"chunk {index} (readings from {start} on, zero-based): {exc}",
                    parameter=exc.parameter,
                ) from exc
            start += readings.shape[0]
            if readings.shape[0]:
                yield frequency, readings if self.dark is None else readings - self.dark, monitor

    def _check_layout(self, ports: int, monitored: bool) -> None:
        if self._layout is None:
            self._layout = (ports, monitored)
            self.dark = check_dark(self._dark_w, ports)
        elif self._layout != (ports, monitored):
            first_ports, first_monitored = self._layout
            raise InputError(
                f"it has {ports} ports {'with' if monitored else 'without'} a power monitor, "
                f"the first chunk {first_ports} {'with' if first_monitored else 'without'} "
                "one: give every chunk the same port columns and either always or never a "
                "monitor"
            )
