"""Per-reading quality flags: a bit mask that says when a reading cannot be trusted.

Every calibrator's :meth:`~wavemeter.calibration.contract.base.BaseCalibrator.flags` returns
one integer per reading whose bits are :class:`ReadingFlag` members: ``OFF_MODEL`` (1),
``OUTSIDE_SPAN`` (2), ``POWER_RANGE`` (4), ``INVALID`` (8), ``TEMPERATURE_RANGE`` (16),
``ORDER_AMBIGUOUS`` (32). The pure functions here decide each rule
(:func:`off_model_threshold`, :func:`power_flags`, :func:`temperature_flags`) from the
thresholds below; the calibrators supply the numbers.

The rule behind each bit: the docs' fit-diagnostics page
(``docs/theory/diagnostics.rst``, "The rules of the reading flags"); what each bit means
for a user and what to do: the user guide's sweep page ("Flags"). How ``OFF_MODEL``'s
distribution is scaled when the sweep shows a model error:
:mod:`~wavemeter.calibration.contract.off_model`.
"""

from __future__ import annotations

import enum

import numpy as np
from scipy import special

__all__ = [
    "ReadingFlag",
    "flag_summary",
    "OFF_MODEL_P_VALUE",
    "POWER_RANGE_FACTOR",
    "UNCHECKED_OFFSET_FACTOR",
    "NO_LIGHT_FRACTION",
    "SPAN_MARGIN_STD",
    "TEMPERATURE_MARGIN_FRACTION",
    "TEMPERATURE_MARGIN_STD",
    "temperature_flags",
    "off_model_threshold",
    "power_flags",
    "flag_counts",
]

OFF_MODEL_P_VALUE = 1e-6
POWER_RANGE_FACTOR = 2.0
UNCHECKED_OFFSET_FACTOR = 1.05
NO_LIGHT_FRACTION = 0.01
#: a reading's frequency must leave a partial span by this many standard deviations
SPAN_MARGIN_STD = 5.0
#: a reading's temperature must leave the calibrated range by this fraction of it ...
TEMPERATURE_MARGIN_FRACTION = 0.1
#: ... or by this many sensor standard deviations, whichever is more
TEMPERATURE_MARGIN_STD = 5.0


class ReadingFlag(enum.IntFlag):
    """Bits of the per-reading quality mask (0: nothing to report).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> readings = powers[:3].copy()
    >>> readings[1] = np.nan  # a reading the instrument could not make
    >>> readings[2] *= 4  # four times the power of the sweep
    >>> flags = cal.flags(readings)
    >>> [wm.ReadingFlag(int(bits)) for bits in flags]
    [<ReadingFlag: 0>, <ReadingFlag.INVALID: 8>, <ReadingFlag.POWER_RANGE: 4>]
    >>> bool(flags[2] & wm.ReadingFlag.POWER_RANGE)
    True
    """

    OFF_MODEL = 1
    OUTSIDE_SPAN = 2
    POWER_RANGE = 4
    INVALID = 8
    TEMPERATURE_RANGE = 16
    ORDER_AMBIGUOUS = 32


def off_model_threshold(ports: int, noise_dof: float) -> float:
    """Chi-square distance (unitless) above which a reading is ``OFF_MODEL``.

    Parameters
    ----------
    ports : int
        Number of ports ``n``; the fit of phase and power leaves ``n - 2`` degrees of freedom.
    noise_dof : float
        Degrees of freedom of the calibrated noise estimate (``inf`` for a known noise).

    Returns
    -------
    float
        ``(n - 2) F^-1(1 - OFF_MODEL_P_VALUE; n - 2, noise_dof)``.
    """
    free = ports - 2
    return float(free * special.fdtri(free, noise_dof, 1.0 - OFF_MODEL_P_VALUE))


def power_flags(total_w: np.ndarray, calibrated_range_w, offsets_known: bool) -> np.ndarray:
    """``INVALID`` (no light) and ``POWER_RANGE`` bits from each reading's total power.

    Parameters
    ----------
    total_w : ndarray, shape (N,)
        Sum of the dark-corrected port readings (W); NaN for a reading with a NaN.
    calibrated_range_w : None or (float, float)
        Smallest and largest total power of the calibration sweep (W); None (a file of an
        older version) skips both tests.
    offsets_known : bool
        The calibration measured (dark readings) or fitted the detector offsets; if not,
        the margin is ``UNCHECKED_OFFSET_FACTOR`` instead of ``POWER_RANGE_FACTOR``.

    Returns
    -------
    ndarray of int, shape (N,)
    """
    flags = np.zeros(total_w.shape, dtype=np.int64)
    if calibrated_range_w is None:
        return flags
    low, high = calibrated_range_w
    factor = POWER_RANGE_FACTOR if offsets_known else UNCHECKED_OFFSET_FACTOR
    with np.errstate(invalid="ignore"):
        dark = total_w < NO_LIGHT_FRACTION * low
        outside = (total_w < low / factor) | (total_w > high * factor)
    flags[dark] |= ReadingFlag.INVALID
    flags[outside] |= ReadingFlag.POWER_RANGE
    return flags


def flag_counts(flags) -> dict[str, int]:
    """Readings with each bit set, by bit name (bits no reading has are left out)."""
    mask = np.asarray(flags, dtype=np.int64)
    counts = {bit.name: int(np.count_nonzero(mask & bit)) for bit in ReadingFlag}
    return {name: count for name, count in counts.items() if count}


def flag_summary(counts: dict[str, int], flagged: int, readings: int) -> str:
    """``flagged 12 of 1000 readings: OFF_MODEL 10, OUTSIDE_SPAN 2``: the words every command
    and the report count flags in (a reading may have several bits, so the counts can add
    up to more than the readings flagged).

    Parameters
    ----------
    counts : dict of str to int
        Readings with each bit, by bit name (:func:`flag_counts`).
    flagged : int
        Readings with any bit.
    readings : int
        Readings in all.
    """
    text = f"flagged {flagged} of {readings} readings"
    listed = ", ".join(f"{name} {count}" for name, count in counts.items())
    return f"{text}: {listed}" if listed else text


def temperature_flags(
    temperature_k: np.ndarray, range_k: tuple[float, float], sensor_std_k: float
) -> np.ndarray:
    """``TEMPERATURE_RANGE`` bits of readings at chip temperatures ``temperature_k`` (K).

    Parameters
    ----------
    temperature_k : ndarray, shape (N,)
        Chip temperature of each reading (K).
    range_k : (float, float)
        Lowest and highest calibration temperature (K).
    sensor_std_k : float
        Standard deviation of the temperature sensor (K).

    Returns
    -------
    ndarray of int64, shape (N,)
    """
    low, high = range_k
    margin = max(TEMPERATURE_MARGIN_FRACTION * (high - low), TEMPERATURE_MARGIN_STD * sensor_std_k)
    outside = (temperature_k < low - margin) | (temperature_k > high + margin)
    return np.where(outside, np.int64(ReadingFlag.TEMPERATURE_RANGE), np.int64(0))
