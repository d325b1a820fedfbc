"""Do readings given as one reference line scatter like one line? Checked before re-anchoring.

Readings of one line retrieve phases that scatter by the calibration's per-reading standard
deviation ``s_i`` (rad). For a line of ``k >= 2`` readings the variance ratio

    F = sum_i w_i wrap(t_i - m)^2 / (k - 1),   w_i = 1 / s_i^2,

``m`` the weighted circular mean, is F(k - 1, nu) distributed (``nu`` the degrees of freedom
of the calibration's noise estimate; chi-square over ``k - 1`` without one). Each line gets
``p = P(F' >= F)``; over the ``L`` lines tested the family-wise p-value is
``min(1, L min p)`` (Bonferroni). The verdict:

* ``"refused"``: family-wise p below ``REFUSE_P_VALUE`` and a line's scatter more than
  ``REFUSE_SCATTER_RATIO`` times the expected one: not readings of one line (an
  :class:`~wavemeter.exceptions.InputError` with the numbers);
* ``"warned"``: family-wise p below ``WARN_P_VALUE`` otherwise: one line, scattering more
  than the calibration's noise (a :class:`~wavemeter.exceptions.CalibrationWarning`);
* ``"ok"``, or ``"untested"`` when no line has two readings.

The thresholds and why: the user guide's re-anchoring section.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import stats

from ...exceptions import CalibrationWarning, InputError
from ...model.cone import wrap_phase_rad

__all__ = [
    "REFERENCE_CAUSE",
    "REFUSE_P_VALUE",
    "REFUSE_SCATTER_RATIO",
    "WARN_P_VALUE",
    "LineScatter",
    "ReferenceCheck",
    "check_reference_scatter",
    "reference_scatter",
]

#: family-wise p-value below which a line's scatter is beyond the calibration's noise
WARN_P_VALUE = 1e-3
#: family-wise p-value below which, with the ratio below, the readings are refused
REFUSE_P_VALUE = 1e-6
#: scatter (standard deviation) over the expected one beyond which readings are not of one
#: line: 100 times the variance, more than a reference laser's jitter or a chip drifting
#: during the readings gives a line read at the noise the calibration measured
REFUSE_SCATTER_RATIO = 10.0
#: the cause of the warning that a line scatters more than the calibration's noise
REFERENCE_CAUSE = "reference_scatter"
REFERENCE_REMEDY = (
    "check that the reference laser was locked and the chip's temperature steady while the "
    "readings were taken, and that every reading is of the line given; the line's own "
    "spread is used for its uncertainty"
)
#: smallest per-reading phase standard deviation (rad): float64 rounding of a phase
_MIN_PHASE_STD_RAD = np.pi * np.finfo(float).eps


@dataclass(frozen=True)
class LineScatter:
    """How the readings of one line scatter about their mean phase.

    Attributes
    ----------
    line_hz : float
        The line's known frequency (Hz).
    readings : int
        Its readings ``k``.
    observed_rad, expected_rad : float
        Their standard deviation about the line's mean, and the calibration's per-reading
        one (RMS over the readings), rad; NaN for one reading.
    ratio : float
        ``sqrt(F)``: the scatter in units of the expected one (NaN for one reading).
    p_value : float or None
        ``P(F' >= F)``; None for one reading (untested).
    """

    line_hz: float
    readings: int
    observed_rad: float
    expected_rad: float
    ratio: float
    p_value: float | None

    def record(self) -> dict:
        return {
            "line_hz": self.line_hz,
            "readings": self.readings,
            "observed_scatter_rad": None if self.p_value is None else self.observed_rad,
            "expected_scatter_rad": None if self.p_value is None else self.expected_rad,
            "scatter_ratio": None if self.p_value is None else self.ratio,
            "p_value": self.p_value,
        }


@dataclass(frozen=True)
class ReferenceCheck:
    """The scatter of every line, the family-wise p-value and the verdict.

    Attributes
    ----------
    lines : tuple of LineScatter
    p_value : float or None
        ``min(1, L min p)`` over the ``L`` lines tested; None when none was.
    verdict : {"ok", "warned", "refused", "untested"}
    noise_dof : float or None
        Degrees of freedom of the calibration's noise (the F test's denominator).
    reported : int or None
        Index in ``lines`` of the line the verdict is about: the refused one of the largest
        ratio, else the one of the smallest p-value (None when none was tested).
    """

    lines: tuple[LineScatter, ...]
    p_value: float | None
    verdict: str
    noise_dof: float | None
    reported: int | None = None

    def record(self) -> dict:
        """JSON-ready ``diagnostics_["reanchor"]["reference_check"]``."""
        return {
            "verdict": self.verdict,
            "p_value": self.p_value,
            "noise_dof": self.noise_dof,
            "warn_p_value": WARN_P_VALUE,
            "refuse_p_value": REFUSE_P_VALUE,
            "refuse_scatter_ratio": REFUSE_SCATTER_RATIO,
            "lines": [line.record() for line in self.lines],
        }

    def text(self) -> str:
        """The reported line's numbers in words."""
        line = self.lines[self.reported]
        tested = sum(item.p_value is not None for item in self.lines)
        test = "F" if self.noise_dof is not None else "chi-square"
        dof = f"{line.readings - 1}" + (
            f" and {self.noise_dof:.4g}" if self.noise_dof is not None else ""
        )
        return (
            f"the {line.readings} readings given as the line at {line.line_hz / 1e12:.6f} THz "
            f"scatter by {line.observed_rad:.3g} rad in phase where the calibration's noise "
            f"predicts {line.expected_rad:.3g} rad ({line.ratio:.3g} times; {test} test on "
            f"{dof} degrees of freedom, p = {min(1.0, tested * line.p_value):.3g} for "
            f"{tested} line(s) tested)"
        )


def reference_scatter(
    phase_rad, frequency_hz, reading_phase_std_rad, noise_dof: float | None = None
) -> ReferenceCheck:
    """How readings of reference lines scatter against the calibration's noise (module
    docstring); no warning, no error.

    Parameters
    ----------
    phase_rad : array_like, shape (N,)
        Phase retrieved from each reading (rad).
    frequency_hz : array_like, shape (N,)
        Its known frequency (Hz); equal values are one line.
    reading_phase_std_rad : array_like, shape (N,)
        The calibration's standard deviation of each reading's phase (rad).
    noise_dof : float or None
        Degrees of freedom of the calibration's noise estimate (None: known exactly).

    Returns
    -------
    ReferenceCheck
    """
    phase = np.asarray(phase_rad, dtype=float)
    frequency = np.asarray(frequency_hz, dtype=float)
    std = np.maximum(np.asarray(reading_phase_std_rad, dtype=float), _MIN_PHASE_STD_RAD)
    lines = []
    for line_hz in np.unique(frequency):
        rows = frequency == line_hz
        count = int(rows.sum())
        weight = 1.0 / std[rows] ** 2
        mean = np.angle(np.sum(weight * np.exp(1j * phase[rows])))
        deviation = wrap_phase_rad(phase[rows] - mean)
        expected = float(np.sqrt(np.mean(std[rows] ** 2)))
        if count < 2:
            lines.append(LineScatter(float(line_hz), count, np.nan, expected, np.nan, None))
            continue
        ratio_squared = float(np.sum(weight * deviation**2) / (count - 1))
        if noise_dof is None:
            p_value = stats.chi2.sf(ratio_squared * (count - 1), count - 1)
        else:
            p_value = stats.f.sf(ratio_squared, count - 1, noise_dof)
        observed = float(np.sqrt(np.sum(deviation**2) / (count - 1)))
        lines.append(
            LineScatter(
                float(line_hz), count, observed, expected, ratio_squared**0.5, float(p_value)
            )
        )
    tested = [index for index, line in enumerate(lines) if line.p_value is not None]
    if not tested:
        return ReferenceCheck(tuple(lines), None, "untested", noise_dof)
    family = min(1.0, len(tested) * min(lines[index].p_value for index in tested))
    refusing = [
        index
        for index in tested
        if lines[index].ratio > REFUSE_SCATTER_RATIO
        and len(tested) * lines[index].p_value < REFUSE_P_VALUE
    ]
    if refusing:
        reported = max(refusing, key=lambda index: lines[index].ratio)
        verdict = "refused"
    else:
        reported = min(tested, key=lambda index: lines[index].p_value)
        verdict = "warned" if family < WARN_P_VALUE else "ok"
    return ReferenceCheck(tuple(lines), family, verdict, noise_dof, reported)


def check_reference_scatter(
    phase_rad, frequency_hz, reading_phase_std_rad, noise_dof: float | None = None
) -> ReferenceCheck:
    """:func:`reference_scatter`, refusing or warning as its verdict says.

    Raises
    ------
    InputError
        (``parameter="frequency_hz"``) When the readings are not of the lines given: the
        observed and expected scatter, the ratio, the p-value and the readings.

    Warns
    -----
    CalibrationWarning
        (cause ``"reference_scatter"``) When a line scatters more than the calibration's
        noise, short of the refusal.
    """
    check = reference_scatter(phase_rad, frequency_hz, reading_phase_std_rad, noise_dof)
    if check.verdict == "refused":
        raise InputError(
            f"reference readings: {check.text()}, beyond {REFUSE_SCATTER_RATIO:g} times at "
            f"p < {REFUSE_P_VALUE:g}: they are not readings of one line at the calibration's "
            "noise, and their mean would move the calibration by an arbitrary phase. Give "
            "each reading its own known frequency, or readings of the given line only",
            parameter="frequency_hz",
        )
    if check.verdict == "warned":
        warnings.warn(reference_warning(check), stacklevel=3)
    return check


def reference_warning(check: ReferenceCheck) -> CalibrationWarning:
    """The warning of a line that scatters more than the calibration's noise."""
    return CalibrationWarning(
        f"re-anchoring: {check.text()}, below p = {WARN_P_VALUE:g}: more than the "
        f"calibration's noise; {REFERENCE_REMEDY}",
        cause=REFERENCE_CAUSE,
        remedy=REFERENCE_REMEDY,
    )
