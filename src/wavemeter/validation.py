"""Input checks shared by every calibrator: one place for the messages users read."""

from __future__ import annotations

import numbers

import numpy as np

from .exceptions import InputError, NotFittedError, shown

__all__ = [
    "as_rng",
    "check_powers",
    "check_dark",
    "reading_array",
    "check_frequency",
    "check_monitor",
    "check_per_reading",
    "check_coarse_inside",
    "check_positive",
    "check_choice",
    "check_fitted",
    "MIN_SAMPLES",
]

MIN_SAMPLES = 4


def as_rng(rng) -> np.random.Generator:
    """A numpy Generator from ``None``, an int seed or a Generator."""
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or (isinstance(rng, (int, np.integer)) and not isinstance(rng, bool)):
        return np.random.default_rng(rng)
    raise InputError(f"rng must be None, an int seed or a numpy Generator, got {shown(rng)}")


def check_positive(name: str, value, *, upper: float | None = None) -> float:
    """A finite real number > 0 (and < ``upper`` when given), or an :class:`InputError`
    naming the parameter."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(
            f"{name} must be a real number, got {type(value).__name__} {value!r}", parameter=name
        )
    value = float(value)
    if not np.isfinite(value) or value <= 0 or (upper is not None and value >= upper):
        allowed = f"in (0, {upper})" if upper is not None else "a finite number > 0"
        raise InputError(f"{name} must be {allowed}, got {value!r}", parameter=name)
    return value


def check_finite(name: str, value) -> float:
    """A finite real number, or an :class:`InputError` naming the parameter."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value):
        raise InputError(f"{name} must be a finite real number, got {value!r}", parameter=name)
    return float(value)


def check_non_negative(name: str, value) -> float:
    """A finite real number >= 0 (a noise level), or an :class:`InputError` naming it."""
    value = check_finite(name, value)
    if value < 0:
        raise InputError(f"{name} must be >= 0, got {value!r}", parameter=name)
    return value


def check_choice(name: str, value, allowed: tuple) -> str:
    """One of ``allowed``, or an error naming the parameter, the choices and the value."""
    if value not in allowed:
        raise InputError(f"{name} must be one of {', '.join(map(repr, allowed))}; got {value!r}")
    return value


def reading_array(powers, *, ports: int | None = None) -> np.ndarray:
    """Port readings as a float64 array of shape (N, n), n >= 3, values unchecked.

    A 1-D array of ``ports`` values is one reading. NaN, inf and dark rows pass: callers
    that must refuse them use :func:`check_powers`; quality flags mark them instead.
    """
    try:
        array = np.asarray(powers, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"port powers must be numeric, got {type(powers).__name__}") from exc
    if array.ndim == 1 and ports is not None and array.size == ports:
        array = array[np.newaxis, :]
    if array.ndim != 2:
        raise InputError(
            f"port powers must be a 2-D array (samples, ports), got shape {array.shape}"
        )
    n = array.shape[1]
    if n < 3:
        raise InputError(f"port powers need at least 3 ports (columns), got {n}")
    if ports is not None and n != ports:
        raise InputError(f"port powers have {n} ports but the calibration has {ports}")
    return array


def check_powers(powers, *, min_samples: int = 1, ports: int | None = None) -> np.ndarray:
    """Port readings as a float64 array of shape (N, n) with n >= 3 (a view when possible;
    callers never write to it).

    Rejects non-numeric input, NaN/inf, rows whose total power is zero or negative (single
    readings may dip below zero by noise) and a port count different from ``ports``.
    """
    array = reading_array(powers, ports=ports)
    samples, n = array.shape
    if samples < min_samples:
        raise InputError(f"need at least {min_samples} samples, got {samples}")
    # one pass over the data: a row sum is NaN/inf when any reading is, and <= 0 in the dark
    total = array @ np.ones(n)
    if not np.all(np.isfinite(total) & (total > 0)):
        bad = ~np.isfinite(array).all(axis=1)
        if bad.any():
            rows = np.flatnonzero(bad)[:5].tolist()
            raise InputError(
                f"port powers contain NaN or inf in rows {rows} (zero-based); drop them"
            )
        rows = np.flatnonzero(total <= 0)[:5].tolist()
        raise InputError(
            f"port powers sum to zero or less in rows {rows} (zero-based): no light, or "
            "readings that are not linear powers (dBm read as W?)"
        )
    return array


def check_frequency(frequency_hz, samples: int, name: str = "frequency_hz") -> np.ndarray:
    """Frequencies (Hz) as a fresh finite float64 vector of length ``samples``."""
    try:
        f = np.array(frequency_hz, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric, got {type(frequency_hz).__name__}") from exc
    if f.ndim != 1 or f.size != samples:
        raise InputError(f"{name} must be a vector of {samples} values, got shape {f.shape}")
    if not np.all(np.isfinite(f)):
        raise InputError(f"{name} contains NaN or inf")
    return f


def check_per_reading(name: str, value, samples: int, *, finite: bool = True) -> np.ndarray:
    """One number, or one per reading, as a fresh float64 vector of length ``samples``;
    finite unless ``finite`` is False (NaN then marks a reading whose input is missing)."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"{name} must be a number or an array of numbers, got {type(value).__name__}"
        ) from exc
    if array.ndim == 0:
        array = np.full(samples, float(array))
    if array.shape != (samples,):
        raise InputError(
            f"{name} must be one value or one per reading ({samples}), got shape {array.shape}"
        )
    if finite and not np.all(np.isfinite(array)):
        raise InputError(f"{name} contains NaN or inf")
    return array


def check_dark(dark_w, ports: int) -> np.ndarray | None:
    """Per-port dark readings (W): None, or ``ports`` finite values (signed: an offset)."""
    if dark_w is None:
        return None
    try:
        dark = np.array(dark_w, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"dark_w must be {ports} numbers (W), got {dark_w!r:.80}") from exc
    if dark.shape != (ports,) or not np.all(np.isfinite(dark)):
        raise InputError(
            f"dark_w must be {ports} finite numbers (W), one per port, got {dark.size}",
            parameter="dark_w",
        )
    return dark


def check_monitor(power_monitor_w, samples: int) -> np.ndarray | None:
    """Power-monitor readings (W): None, or positive finite values, one per sample."""
    if power_monitor_w is None:
        return None
    m = np.array(np.broadcast_to(np.asarray(power_monitor_w, dtype=float), (samples,)))
    if not np.all(np.isfinite(m)) or np.any(m <= 0):
        raise InputError("power_monitor_w must be finite and > 0 for every sample (W)")
    return m


def check_fitted(estimator, attribute: str = "fsr_hz_") -> None:
    """Raise :class:`NotFittedError` unless ``estimator`` has been fitted."""
    if not hasattr(estimator, attribute):
        raise NotFittedError(
            f"this {type(estimator).__name__} is not fitted yet: call fit(powers, frequency_hz) "
            "or load a calibration file first"
        )


def check_coarse_inside(
    coarse_hz: np.ndarray, inside: np.ndarray, outside_text: str, parameter: str | None = None
) -> None:
    """Raise for the first coarse frequency (Hz) not ``inside`` (bool per reading): its value,
    its row (zero-based) and how many in all are ``outside_text`` (where the calibration has
    no map), and what to do."""
    outside = ~np.asarray(inside, dtype=bool)
    if outside.any():
        first = int(np.flatnonzero(outside)[0])
        raise InputError(
            f"coarse_hz {shown(coarse_hz[first])} Hz (reading {first}, zero-based; "
            f"{int(outside.sum())} in all) is {outside_text}; calibrate over a sweep that "
            "covers it",
            parameter=parameter,
        )
