"""The checks of :func:`~wavemeter.analysis.noise.frequency_noise`'s inputs, and the gaps.

The series (finite numbers, at least ``MIN_READINGS``, absolute and not constant), the
meter's standard deviation and the floor it gives, the rates, fractions and observation
time; each refusal an :class:`~wavemeter.exceptions.InputError` naming its parameter.
NaN readings are excluded: those at the ends are dropped, runs of up to
``MAX_BRIDGED_RUN`` inside are bridged by linear interpolation (:func:`bridge`; a longer
gap is an error: analyse the parts on either side).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError, shown
from ..validation import check_non_negative, check_positive

__all__ = [
    "MIN_READINGS",
    "MAX_BRIDGED_RUN",
    "check_series",
    "check_meter_std",
    "optional_positive",
    "bridge",
    "check_fraction",
    "check_center",
    "check_observation_time",
]

#: fewest finite readings analysed
MIN_READINGS = 100
#: longest run of NaN readings inside the record that is bridged by interpolation
MAX_BRIDGED_RUN = 8


def check_series(frequency_hz) -> np.ndarray:
    try:
        series = np.array(frequency_hz, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"frequency_hz must be numbers (Hz), got {type(frequency_hz).__name__}",
            parameter="frequency_hz",
        ) from exc
    if series.ndim != 1:
        raise InputError(
            f"frequency_hz must be a vector of readings (Hz), got shape {series.shape}",
            parameter="frequency_hz",
        )
    infinite = np.flatnonzero(np.isinf(series))
    if infinite.size:
        raise InputError(
            f"frequency_hz is infinite at reading {int(infinite[0])} (zero-based; "
            f"{infinite.size} in all); mark readings to exclude as NaN",
            parameter="frequency_hz",
        )
    finite = int(np.count_nonzero(np.isfinite(series)))
    if finite < MIN_READINGS:
        raise InputError(
            f"frequency_hz has {finite} finite readings (of {series.size}); a noise "
            f"analysis needs at least {MIN_READINGS}: record longer",
            parameter="frequency_hz",
        )
    return series


def check_meter_std(meter_std_hz, series: np.ndarray, rate_hz: float) -> float | None:
    """The meter's floor ``2 mean(sigma^2) / rate`` (Hz^2/Hz) over the finite readings."""
    if meter_std_hz is None:
        return None
    try:
        sigma = np.array(meter_std_hz, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"meter_std_hz must be a number or one per reading (Hz), got "
            f"{type(meter_std_hz).__name__}",
            parameter="meter_std_hz",
        ) from exc
    if sigma.ndim == 0:
        sigma = np.full(series.size, float(sigma))
    if sigma.shape != series.shape:
        raise InputError(
            f"meter_std_hz must be one value or one per reading ({series.size}), got shape "
            f"{sigma.shape}",
            parameter="meter_std_hz",
        )
    used = sigma[np.isfinite(series)]
    if not np.all(np.isfinite(used) & (used >= 0)):
        raise InputError(
            "meter_std_hz must be finite and >= 0 (Hz) for every finite reading",
            parameter="meter_std_hz",
        )
    return float(2.0 * np.mean(used**2) / rate_hz)


def optional_positive(name: str, value) -> float | None:
    return None if value is None else check_positive(name, value)


def bridge(series: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop NaN at the ends, bridge inner runs of up to ``MAX_BRIDGED_RUN`` NaN linearly:
    the series and which of its readings were measured (not bridged)."""
    finite = np.isfinite(series)
    first, last = np.flatnonzero(finite)[[0, -1]]
    kept = series[first : last + 1].copy()
    measured = finite[first : last + 1]
    if measured.all():
        return kept, measured
    edges = np.diff(np.concatenate(([0], (~measured).astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = int(np.argmax(stops - starts))
    if stops[longest] - starts[longest] > MAX_BRIDGED_RUN:
        raise InputError(
            f"frequency_hz has a gap of {stops[longest] - starts[longest]} NaN readings "
            f"from reading {first + starts[longest]} (zero-based); at most "
            f"{MAX_BRIDGED_RUN} in a row are bridged: analyse the parts before and after "
            "the gap separately",
            parameter="frequency_hz",
        )
    positions = np.arange(kept.size)
    kept[~measured] = np.interp(positions[~measured], positions[measured], kept[measured])
    return kept, measured


def check_fraction(name: str, value, *, upper: float | None = None) -> float:
    value = check_non_negative(name, value)
    if upper is not None and not 0 < value < upper:
        raise InputError(f"{name} must be in (0, {upper:g}), got {value!r}", parameter=name)
    return value


def check_center(raw: np.ndarray) -> float:
    """The mean of the finite readings (Hz), which must be > 0 and not all equal."""
    finite = raw[np.isfinite(raw)]
    center_hz = float(np.mean(finite))
    if center_hz <= 0:
        raise InputError(
            f"frequency_hz must be absolute frequencies (Hz), mean > 0, got mean "
            f"{shown(center_hz)}: the fractional frequency is relative to it",
            parameter="frequency_hz",
        )
    if np.ptp(finite) == 0:
        raise InputError(
            f"frequency_hz is constant ({shown(center_hz)} Hz in every reading): there is no "
            "noise to analyse; check that the readings are frequencies, not a fill value",
            parameter="frequency_hz",
        )
    return center_hz


def check_observation_time(value, duration_s: float) -> float | None:
    if value is None:
        return None
    value = check_positive("observation_time_s", value)
    if value > duration_s * (1 + 1e-9):
        raise InputError(
            f"observation_time_s {value!r} s is longer than the record ({duration_s:.6g} s): "
            "the PSD below 1 / T is not measured; give at most the record length, or record "
            "longer",
            parameter="observation_time_s",
        )
    return value
