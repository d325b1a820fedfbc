"""The sanity check of a reference laser's readings before they re-anchor the meter.

:func:`check_window` judges a window of readings of a reference of known frequency (their
errors, reading - known) and fits the meter's offset. The checks, each refusing good
readings with probability ``p``:

- every reading unflagged;
- no lone reading off its neighbours (the second difference ``e_i - (e_i-1 + e_i+1) / 2``,
  of variance ``1.5 sigma^2``) by more than the largest of ``n`` normal deviates, in the
  larger of the stated and the robust (MAD) scale;
- the reading-to-reading scatter (the successive-difference estimate ``sum (e_i+1 - e_i)^2
  / 2 (n - 1)``, blind to a smooth drift, with ``2 (n - 1)^2 / (3 n - 4)`` degrees of
  freedom) at the stated uncertainty, within chi-squared bounds;
- the meter's offset as a straight line in time over the latest part of the window that
  is one (halved while the residuals exceed the scatter, or those of its latest quarter
  leave the line, at :data:`BEND_P`: a bend in the drift is soon left behind),
  extrapolated to the time the anchor is for: its slope within the meter's fastest drift,
  and its change from the anchor in force within what the drift explains since.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

from ..calibration import ReadingFlag

__all__ = ["WindowCheck", "check_window", "P_FALSE", "STD_SLACK", "MIN_FIT_READINGS"]

#: probability that each check refuses a window of good readings
P_FALSE = 1e-6
#: the stated uncertainty includes the calibration's own part, which readings of one line do
#: not scatter by: the scatter may fall this fraction below the chi-squared lower bound
STD_SLACK = 0.2
#: fewest readings a line is fitted to (a window is halved down to no fewer)
MIN_FIT_READINGS = 20
#: a window is halved while its residuals about the line exceed the scatter at this
#: probability (a needless halving only adds noise, so it may come early)
BEND_P = 1e-3
_BEND_Z = float(stats.norm.isf(BEND_P / 2))
#: the median absolute deviation of normal values times this is their standard deviation
_MAD_TO_STD = 1.482602218505602


@dataclass(frozen=True)
class WindowCheck:
    """The verdict on a window of reference readings.

    Attributes
    ----------
    ok : bool
        Whether the window may re-anchor the meter.
    reason : str
        Why not ("" when ok).
    readings : int
        Readings in the window.
    fitted : int
        The latest readings the line was fitted to.
    offset_hz : float
        The meter's offset (reading - known, Hz) the line gives at the anchor's time.
    offset_std_hz : float
        Its standard error (Hz).
    drift_hz_per_s : float
        The line's slope (Hz/s).
    correction_hz : float
        ``offset_hz`` minus the offset the anchor in force corrects (Hz).
    scatter_ratio : float
        The reading-to-reading scatter over the stated uncertainty.
    worst_z : float
        The largest deviation of a reading from its neighbours, in standard deviations.
    allowance_hz : float
        The largest correction the meter's drift explains (Hz).
    """

    ok: bool
    reason: str
    readings: int
    fitted: int
    offset_hz: float
    offset_std_hz: float
    drift_hz_per_s: float
    correction_hz: float
    scatter_ratio: float
    worst_z: float
    allowance_hz: float

    def describe(self) -> dict:
        return asdict(self)


def check_window(
    time_s,
    error_hz,
    frequency_std_hz,
    flags,
    *,
    at_s: float,
    anchored_hz: float,
    allowance_hz: float,
    max_drift_hz_per_s: float,
    p_false: float = P_FALSE,
) -> WindowCheck:
    """Judge readings of a reference laser.

    Parameters
    ----------
    time_s : ndarray, shape (N,)
        When each was taken (s), increasing.
    error_hz : ndarray, shape (N,)
        Each reading minus the reference's known frequency (Hz), read with one calibration.
    frequency_std_hz : ndarray, shape (N,)
        Their stated standard deviations (Hz).
    flags : ndarray of int, shape (N,)
        Their :class:`~wavemeter.ReadingFlag` bits.
    at_s : float
        The time (s) the offset is wanted for.
    anchored_hz : float
        The offset the anchor in force corrects (Hz, in the same calibration's terms).
    allowance_hz : float
        The largest change of the offset the meter's drift explains since that anchor (Hz).
    max_drift_hz_per_s : float
        The fastest the meter drifts (Hz/s).
    p_false : float
        The probability that each check refuses good readings.

    Returns
    -------
    WindowCheck
    """
    times = np.asarray(time_s, dtype=float)
    error = np.asarray(error_hz, dtype=float)
    std = np.asarray(frequency_std_hz, dtype=float)
    flags = np.asarray(flags, dtype=np.int64)
    n = len(error)
    found = {"fitted": 0, "scatter_ratio": math.nan, "worst_z": math.nan}
    line = (math.nan, math.nan, math.nan, math.inf)

    def verdict(reason: str) -> WindowCheck:
        offset, offset_std, slope, _ = line
        return WindowCheck(
            ok=not reason,
            reason=reason,
            readings=n,
            offset_hz=offset,
            offset_std_hz=offset_std,
            drift_hz_per_s=slope,
            correction_hz=offset - anchored_hz,
            allowance_hz=allowance_hz,
            **found,
        )

    flagged = flags != 0
    if flagged.any():
        bits = int(np.bitwise_or.reduce(flags[flagged]))
        names = ", ".join(flag.name for flag in ReadingFlag if bits & flag)
        return verdict(f"{int(flagged.sum())} of {n} reference readings flagged {names}")
    if not (np.isfinite(error).all() and np.isfinite(std).all() and (std > 0).all()):
        return verdict("a reference reading without a finite value and uncertainty")
    if n < MIN_FIT_READINGS:
        return verdict(f"{n} reference readings, fewer than {MIN_FIT_READINGS}")
    stated = float(np.sqrt(np.mean(std**2)))
    found["worst_z"] = worst = _worst_deviation(error, std)
    largest = float(stats.norm.isf(p_false / (2 * n)))
    if worst > largest:
        return verdict(
            f"a reference reading lies {worst:.3g} standard deviations off its neighbours; at "
            f"most {largest:.3g} is expected of {n} readings"
        )
    noise = math.sqrt(np.sum(np.diff(error) ** 2) / (2 * (n - 1)))
    found["scatter_ratio"] = scatter = noise / stated
    dof = 2 * (n - 1) ** 2 / (3 * n - 4)
    high = math.sqrt(stats.chi2.isf(p_false, dof) / dof)
    low = math.sqrt(stats.chi2.ppf(p_false, dof) / dof) * (1.0 - STD_SLACK)
    if not low <= scatter <= high:
        return verdict(
            f"the reference readings scatter by {scatter:.3g} times their stated uncertainty; "
            f"{low:.3g} to {high:.3g} is expected of {n} readings"
        )
    line, found["fitted"] = _latest_line(times, error, noise, at_s)
    offset, offset_std, slope, slope_std = line
    z = float(stats.norm.isf(p_false / 2))
    if abs(slope) > max_drift_hz_per_s + z * slope_std:
        return verdict(
            f"the reference drifts by {slope / 1e6:+.4g} MHz/s; the meter drifts at most "
            f"{max_drift_hz_per_s / 1e6:.4g} MHz/s"
        )
    bound = allowance_hz + z * offset_std
    if abs(offset - anchored_hz) > bound:
        return verdict(
            f"the reference reads {(offset - anchored_hz) / 1e6:+.6g} MHz off the anchor in "
            f"force; the meter's drift explains at most {bound / 1e6:.6g} MHz"
        )
    return verdict("")


def _worst_deviation(error: np.ndarray, std: np.ndarray) -> float:
    """The largest second difference in standard deviations (the larger of the stated and
    the robust scale): a lone reading off its neighbours, whatever the drift."""
    second = (error[1:-1] - 0.5 * (error[:-2] + error[2:])) / (math.sqrt(1.5) * std[1:-1])
    ends = np.abs(error[[0, -1]] - error[[1, -2]]) / (math.sqrt(2.0) * std[[0, -1]])
    z = np.concatenate([second, ends])
    robust = _MAD_TO_STD * float(np.median(np.abs(z - np.median(z))))
    return float(np.max(np.abs(z))) / max(robust, 1.0)


def _latest_line(times, error, noise: float, at_s: float):
    """``((offset, offset_std, slope, slope_std), readings)`` of a line fitted to the
    latest readings that make one, extrapolated to ``at_s``."""
    start = 0
    while True:
        t, e = times[start:], error[start:]
        m = len(e)
        center = float(np.mean(t))
        spread = float(np.sum((t - center) ** 2))
        slope = float(np.sum((t - center) * (e - e.mean())) / spread) if spread > 0 else 0.0
        residual = e - e.mean() - slope * (t - center)
        # bent: the residuals exceed the scatter, or the latest quarter has left the line
        # (a bend just taken shows there first)
        quarter = residual[-(m // 4) :]
        bent = np.sum(residual**2) / noise**2 > stats.chi2.isf(BEND_P, m - 2) or abs(
            quarter.mean()
        ) > _BEND_Z * noise / math.sqrt(len(quarter))
        if not bent or m < 2 * MIN_FIT_READINGS:
            break
        start += m // 2
    offset = float(e.mean() + slope * (at_s - center))
    offset_std = noise * math.sqrt(1.0 / m + ((at_s - center) ** 2 / spread if spread else 0.0))
    slope_std = noise / math.sqrt(spread) if spread > 0 else math.inf
    return (offset, offset_std, slope, slope_std), m
