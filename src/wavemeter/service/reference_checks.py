"""The sanity check of a reference laser's readings before they re-anchor the meter.

:func:`check_window` fits the meter's offset on a window of readings of a reference of known
frequency as a straight line in time (the meter drifts; the line is extrapolated to the
time the new anchor is for) and judges the window: every reading unflagged; no reading off
the line by more than the largest of ``n`` normal deviates at a false-refusal probability
``p`` (a lone corrupt reading); the scatter about the line at the meter's stated
uncertainty (the sample variance over the mean stated variance inside the chi-squared bounds
of ``n - 2`` degrees of freedom at ``p``); the drift rate and the correction within what the
meter's drift can explain (``max_drift_hz_per_s``, and the allowance for the time since the
last anchor) plus their own noise at ``p``. Every bound is a probability, not a tuned
number.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

from ..calibration import ReadingFlag

__all__ = ["WindowCheck", "check_window", "P_FALSE", "STD_SLACK"]

#: probability that each check refuses a window of good readings
P_FALSE = 1e-6
#: the median absolute deviation of normal values times this is their standard deviation
_MAD_TO_STD = 1.482602218505602
#: the stated uncertainty includes the calibration's own part, which readings of one line do
#: not scatter by: the scatter may fall this fraction below the chi-squared lower bound
STD_SLACK = 0.2


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
    offset_hz : float
        The meter's offset (reading - known, Hz) the line gives at the anchor's time.
    offset_std_hz : float
        Its standard error (Hz), from the stated uncertainties.
    drift_hz_per_s : float
        The line's slope (Hz/s).
    correction_hz : float
        ``offset_hz`` minus the offset the anchor in force corrects (Hz).
    scatter_ratio : float
        Sample standard deviation about the line over the stated one.
    worst_z : float
        The largest deviation of a reading from the line, in its stated uncertainty (or the
        readings' robust scatter, where larger).
    allowance_hz : float
        The largest correction the meter's drift explains (Hz).
    """

    ok: bool
    reason: str
    readings: int
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
        When each was taken (s).
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
    flagged = flags != 0
    usable = ~flagged & np.isfinite(error) & np.isfinite(std) & (std > 0)
    offset = offset_std = slope = scatter = worst = math.nan
    if usable.sum() >= 3:
        t, e = times[usable], error[usable]
        stated = float(np.sqrt(np.mean(std[usable] ** 2)))
        center = float(np.mean(t))
        spread = float(np.sum((t - center) ** 2))
        slope = float(np.sum((t - center) * (e - e.mean())) / spread) if spread > 0 else 0.0
        residual = e - e.mean() - slope * (t - center)
        offset = float(e.mean() + slope * (at_s - center))
        offset_std = stated * math.sqrt(
            1.0 / len(e) + ((at_s - center) ** 2 / spread if spread > 0 else 0.0)
        )
        slope_std = stated / math.sqrt(spread) if spread > 0 else math.inf
        scatter = float(np.sqrt(np.sum(residual**2) / (len(e) - 2))) / stated
        # deviations in the larger of the stated and the robust (MAD) scale: a lone outlier
        # stands out of the others, and understated uncertainties are the scatter's case
        z = residual / std[usable]
        robust = _MAD_TO_STD * float(np.median(np.abs(z - np.median(z))))
        worst = float(np.max(np.abs(z))) / max(robust, 1.0)

    def verdict(reason: str) -> WindowCheck:
        return WindowCheck(
            ok=not reason,
            reason=reason,
            readings=n,
            offset_hz=offset,
            offset_std_hz=offset_std,
            drift_hz_per_s=slope,
            correction_hz=offset - anchored_hz,
            scatter_ratio=scatter,
            worst_z=worst,
            allowance_hz=allowance_hz,
        )

    if flagged.any():
        bits = int(np.bitwise_or.reduce(flags[flagged]))
        names = ", ".join(flag.name for flag in ReadingFlag if bits & flag)
        return verdict(f"{int(flagged.sum())} of {n} reference readings flagged {names}")
    if usable.sum() < 3:
        return verdict(f"{n} reference reading(s), fewer than 3 with a value and an uncertainty")
    largest = float(stats.norm.isf(p_false / (2 * n)))
    if worst > largest:
        return verdict(
            f"a reference reading lies {worst:.3g} standard deviations off the others; at most "
            f"{largest:.3g} is expected of {n} readings"
        )
    dof = n - 2
    high = math.sqrt(stats.chi2.isf(p_false, dof) / dof)
    low = math.sqrt(stats.chi2.ppf(p_false, dof) / dof) * (1.0 - STD_SLACK)
    if not low <= scatter <= high:
        return verdict(
            f"the reference readings scatter by {scatter:.3g} times their stated uncertainty; "
            f"{low:.3g} to {high:.3g} is expected of {n} readings"
        )
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
