"""A sweep's absolute frequency axis from a reference cell recorded beside the meter.

:func:`axis_from_phase` takes the meter's phase of every sample (in sweep order), smooths
it along the sweep (the laser's frequency is smooth in time), fits the cell's lines in
that phase, identifies them, fits the correction ``f = g(phi)`` and returns the corrected
axis of every sample with the fit's record. :func:`correct_sweep_axis` does it for a sweep
with a recorded axis, the phase coming from a calibration the caller fitted on that axis
(``phase_of``). The calibration's own uncertainty is not in the budget: the calibrator
fitted on the corrected axis adds it; the axis's share of the meter's own phase noise
(smoothed along the sweep) is told by its bandwidth (``SweepAxis.phase_bandwidth_per_reading``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from .axis import AxisCorrection, fit_axis_correction
from .identify import Identification, identify_lines
from .line_fit import FittedLines, fit_absorption_lines
from .lines import ReferenceLines

__all__ = [
    "SweepAxis",
    "axis_from_phase",
    "correct_sweep_axis",
    "smooth_sweep_phase",
    "DEFAULT_SMOOTHING_SAMPLES",
    "SMOOTHING_STOP_GAIN",
    "smoothing_bandwidth",
]

#: samples of the cubic Savitzky-Golay window that smooths the phase along the sweep
DEFAULT_SMOOTHING_SAMPLES = 101
#: a sample-to-sample phase step beyond this share of pi cannot be unwrapped safely
MAX_PHASE_STEP = 0.5
#: the smoothing passes the meter's phase noise up to the frequency where its gain first
#: falls below this (its power then below 1 %)
SMOOTHING_STOP_GAIN = 0.1


@dataclass(frozen=True)
class SweepAxis:
    """A sweep's corrected axis and how it was found.

    Attributes
    ----------
    frequency_hz : ndarray, shape (N,)
        The corrected frequency of every sample (Hz): ``correction.frequency_hz(phase_rad)``.
    phase_rad : ndarray, shape (N,)
        The meter's unwrapped phase, smoothed along the sweep (rad).
    phase_std_rad : float
        Standard error of the smoothed phase of a sample (rad).
    lines : FittedLines
        The lines fitted in the record (centres in rad of ``phase_rad``).
    identification : Identification
        Which table line each fitted line is.
    correction : AxisCorrection
        The fitted ``g`` with its budget (``correction.budget_hz(phase)``).
    phase_bandwidth_per_reading : float
        Frequency (cycles per reading, along the sweep) up to which the axis follows the
        meter's own phase noise (:func:`smoothing_bandwidth` of the smoothing window): a
        calibration fitted on the axis cannot tell a phase error of the readings that
        changes more slowly from the axis's.
    """

    frequency_hz: np.ndarray
    phase_rad: np.ndarray
    phase_std_rad: float
    lines: FittedLines
    identification: Identification
    correction: AxisCorrection
    phase_bandwidth_per_reading: float

    def budget_hz(self) -> dict:
        """The axis budget (Hz) of every sample, by term and ``"total"``, each shape (N,)."""
        return self.correction.budget_hz(self.phase_rad)

    def budget_at_hz(self, frequency_hz) -> dict:
        """The axis budget (Hz) at frequencies (Hz), by term and ``"total"``: the budget of
        the sweep's samples, interpolated along the corrected axis (constant beyond it).
        What a calibration fitted on the corrected axis adds to its own uncertainty for a
        reading at that frequency."""
        order = np.argsort(self.frequency_hz)
        axis = self.frequency_hz[order]
        frequency = np.asarray(frequency_hz, dtype=float)
        return {
            name: np.interp(frequency, axis, values[order])
            for name, values in self.budget_hz().items()
        }

    @property
    def fsr_hz(self) -> float:
        """The meter's FSR at the middle of the lines (Hz): ``2 pi |dg/dphi|``."""
        slope = self.correction.slope_hz_per_rad(self.correction.phase_center_rad)
        return float(2.0 * np.pi * abs(slope))


def smooth_sweep_phase(phase_rad, window_samples: int | None = None):
    """Unwrap a phase along a sweep and smooth it (cubic Savitzky-Golay).

    Parameters
    ----------
    phase_rad : array_like, shape (N,)
        Phase of every sample in sweep order (rad), wrapped or not; neighbouring samples
        must differ by less than ``MAX_PHASE_STEP * pi`` after unwrapping.
    window_samples : None or int
        Odd window length (default ``DEFAULT_SMOOTHING_SAMPLES``, at most N / 5).

    Returns
    -------
    smoothed : ndarray, shape (N,), rad
    std_rad : float
        Standard error of a smoothed sample: the residuals' robust standard deviation times
        the filter's noise gain.
    """
    from scipy.signal import savgol_coeffs, savgol_filter

    phase = np.asarray(phase_rad, dtype=float).reshape(-1)
    if phase.size < 16 or not np.all(np.isfinite(phase)):
        raise InputError("the sweep's phase must be finite, at least 16 samples")
    unwrapped = np.unwrap(phase)
    step = np.abs(np.diff(unwrapped))
    if np.any(step > MAX_PHASE_STEP * np.pi):
        worst = int(np.argmax(step))
        raise InputError(
            f"the phase jumps by {step[worst]:.3g} rad between samples {worst} and {worst + 1}: "
            "the sweep is too coarse to unwrap (sample more densely than a few per FSR)"
        )
    window = _window(phase.size, window_samples)
    smoothed = savgol_filter(unwrapped, window, 3, mode="interp")
    residual = unwrapped - smoothed
    spread = float(np.median(np.abs(residual - np.median(residual))) / 0.6745)
    gain = float(np.sqrt(np.sum(savgol_coeffs(window, 3) ** 2)))
    return smoothed, spread * gain


def _window(samples: int, window_samples: int | None) -> int:
    """The odd smoothing window (samples) for a sweep of ``samples``; raises below 5."""
    window = DEFAULT_SMOOTHING_SAMPLES if window_samples is None else int(window_samples)
    window = min(window, samples // 5)
    window -= 1 - window % 2
    if window < 5:
        raise InputError(f"the smoothing window must be at least 5 samples, got {window}")
    return window


def smoothing_bandwidth(window_samples: int) -> float:
    """Frequency (cycles per sample) where the gain of :func:`smooth_sweep_phase`'s filter
    (cubic Savitzky-Golay, ``window_samples`` odd) first falls below ``SMOOTHING_STOP_GAIN``.

    Examples
    --------
    >>> from wavemeter.reference import smoothing_bandwidth
    >>> print(f"{smoothing_bandwidth(101):.4f} cycles per sample")
    0.0162 cycles per sample
    """
    from scipy.signal import freqz, savgol_coeffs

    frequency, response = freqz(savgol_coeffs(window_samples, 3), worN=64 * window_samples)
    below = np.abs(response) < SMOOTHING_STOP_GAIN
    return float(frequency[np.argmax(below)] / (2.0 * np.pi)) if below.any() else 0.5


def axis_from_phase(
    phase_rad,
    transmission,
    lines: ReferenceLines,
    *,
    approx_hz=None,
    axis_error_hz: float | None = None,
    band_hz=None,
    direction: int | None = None,
    scale_range=None,
    pressure_pa: float | None = None,
    pressure_std_pa: float = 0.0,
    order: int | None = None,
    smoothing_samples: int | None = None,
) -> SweepAxis:
    """The corrected axis of a sweep from the meter's phase and the cell's record.

    Parameters
    ----------
    phase_rad : array_like, shape (N,)
        The meter's phase of every sample, in sweep order (rad, wrapped or not).
    transmission : array_like, shape (N,)
        The cell channel, one reading per sample.
    lines : ReferenceLines
        The cell's line table.
    approx_hz : None or array_like, shape (N,)
        The recorded axis (Hz), when there is one.
    axis_error_hz, band_hz, direction, scale_range :
        As for :func:`~wavemeter.reference.identify_lines` (``band_hz``: the band the sweep
        covers; ``scale_range``: bounds on ``|df/dphi|``, Hz/rad).
    pressure_pa, pressure_std_pa, order :
        As for :func:`~wavemeter.reference.fit_axis_correction`.
    smoothing_samples : None or int
        Window of :func:`smooth_sweep_phase`.

    Returns
    -------
    SweepAxis

    Raises
    ------
    InputError
        For mismatched lengths, a phase that cannot be unwrapped or is not monotonic along
        the sweep, no line found, or lines that cannot be identified uniquely (the reason).
    """
    phase, phase_std = smooth_sweep_phase(phase_rad, smoothing_samples)
    record = np.asarray(transmission, dtype=float).reshape(-1)
    if record.shape != phase.shape:
        raise InputError(
            f"reference_transmission must have one reading per sample ({phase.size}), got "
            f"{record.size}",
            parameter="reference_transmission",
        )
    fitted = fit_absorption_lines(record, phase)
    approx = None
    if approx_hz is not None:
        axis = np.asarray(approx_hz, dtype=float).reshape(-1)
        if axis.shape != phase.shape:
            raise InputError(f"the recorded axis must have {phase.size} values, one per sample")
        approx = np.interp(fitted.index, np.arange(axis.size), axis)
        if direction is None:
            direction = 1 if np.corrcoef(phase, axis)[0, 1] > 0 else -1
    identification = identify_lines(
        fitted.center,
        lines,
        frequency_std_hz=_line_std_hz(fitted, phase, phase_std, approx, scale_range, lines),
        approx_hz=approx,
        axis_error_hz=axis_error_hz,
        band_hz=band_hz,
        direction=direction,
        scale_range=scale_range,
        pressure_pa=pressure_pa,
    )
    correction = fit_axis_correction(
        fitted.center,
        lines.take(identification.table_index),
        center_std_rad=fitted.center_std,
        phase_std_rad=np.full(len(fitted), phase_std),
        pressure_pa=pressure_pa,
        pressure_std_pa=pressure_std_pa,
        order=order,
    )
    return SweepAxis(
        frequency_hz=correction.frequency_hz(phase),
        phase_rad=phase,
        phase_std_rad=phase_std,
        lines=fitted,
        identification=identification,
        correction=correction,
        phase_bandwidth_per_reading=smoothing_bandwidth(_window(phase.size, smoothing_samples)),
    )


def _line_std_hz(fitted, phase, phase_std, approx, scale_range, lines):
    """Each found line's frequency uncertainty for the identification (Hz): its centre fit
    and the phase noise at it, through the phase scale (from the recorded axis, else the
    middle of ``scale_range``), and the table's median uncertainty; None when no scale is
    known."""
    if approx is not None and approx.size > 1:
        scale = abs(np.polyfit(fitted.center, approx, 1)[0])
    elif scale_range is not None:
        scale = 0.5 * (scale_range[0] + scale_range[1])
    else:
        return None
    spread = np.hypot(fitted.center_std, phase_std) * scale
    return np.hypot(spread, np.median(lines.std_hz))


def correct_sweep_axis(
    powers,
    recorded_hz,
    transmission,
    lines: ReferenceLines,
    *,
    phase_of: Callable[[np.ndarray], np.ndarray],
    axis_error_hz: float | None = None,
    band_hz=None,
    pressure_pa: float | None = None,
    pressure_std_pa: float = 0.0,
    order: int | None = None,
    smoothing_samples: int | None = None,
) -> SweepAxis:
    """Correct a sweep's recorded axis with the reference cell recorded beside the ports.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        The sweep's port readings, in sweep order.
    recorded_hz : array_like, shape (N,)
        The laser's recorded axis (Hz).
    transmission : array_like, shape (N,)
        The cell channel.
    lines : ReferenceLines
        The cell's table.
    phase_of : callable
        ``phase_of(powers) -> phase_rad (N,)``: the meter's phase of the readings from a
        calibration fitted on the recorded axis (e.g. ``lambda p: cal.phase(p,
        coarse_hz=recorded_hz)``); wrapped or unwrapped.
    axis_error_hz : None or float
        Bound on the recorded axis's error (Hz): the nearest table line identifies each
        line when it is below a quarter spacing; otherwise the pattern of spacings.
    band_hz, pressure_pa, pressure_std_pa, order, smoothing_samples :
        As for :func:`axis_from_phase`.

    Returns
    -------
    SweepAxis
        ``frequency_hz`` is the corrected axis to fit the calibration on.
    """
    recorded = np.asarray(recorded_hz, dtype=float).reshape(-1)
    phase = np.asarray(phase_of(powers), dtype=float).reshape(-1)
    if phase.shape != recorded.shape:
        raise InputError(
            f"phase_of returned {phase.size} phases for {recorded.size} samples of the sweep"
        )
    return axis_from_phase(
        phase,
        transmission,
        lines,
        approx_hz=recorded,
        axis_error_hz=axis_error_hz,
        band_hz=band_hz,
        pressure_pa=pressure_pa,
        pressure_std_pa=pressure_std_pa,
        order=order,
        smoothing_samples=smoothing_samples,
    )
