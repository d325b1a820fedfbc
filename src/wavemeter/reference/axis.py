"""The correction of a sweep's frequency axis from identified lines and the meter's phase.

The meter's unwrapped phase ``phi`` is a smooth, monotonic function of the true frequency;
the identified lines give its value at known frequencies. :func:`fit_axis_correction`
fits ``f = g(phi)``, a Legendre series in the phase scaled to the lines' range, by
generalised least squares with the full covariance of the lines' targets (table
uncertainty, line-centre fit, phase noise at the lines, and the pressure shift's
uncertainty, common to all lines). Order 1 is the offset and the scale (the FSR); higher
orders the smooth error and the dispersion. The order is the one of least Bayesian
information criterion ``chi^2 + (K + 1) ln M`` over orders 1 to ``MAX_ORDER`` (at most
``M - 1``, ``M`` lines), with the stated uncertainties.

:class:`AxisCorrection` evaluates ``g`` and the uncertainty budget at any phase: each term
is its covariance propagated through the fit; the interpolation's model error is the
leave-one-line-out residual in excess of what the terms explain.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError, shown
from .lines import ReferenceLines

__all__ = ["AxisCorrection", "BUDGET_TERMS", "MAX_ORDER", "fit_axis_correction"]

#: highest Legendre order of the axis correction considered
MAX_ORDER = 12
#: the budget's terms (the calibration's own term is added by the calibrator), and how each
#: is computed
BUDGET_TERMS = {
    "line_table": "the table's standard uncertainty of each line centre, propagated through "
    "the generalised least-squares fit of the correction",
    "line_center_fit": "each line centre's standard error from its Voigt fit in the "
    "transmission record (Jacobian covariance, residual variance), through the fit",
    "pressure_shift": "the pressure shift coefficients times the stated uncertainty of the "
    "cell's pressure, common to all lines, through the fit (0 when the table gives centres "
    "at the cell's conditions)",
    "phase_interpolation": "the meter's phase noise at the lines (the smoothed phase's "
    "standard error) through the fit, and the model error of the correction between lines "
    "(leave-one-line-out residuals in excess of their expected variance)",
}


def _basis(u: np.ndarray, order: int) -> np.ndarray:
    return np.polynomial.legendre.legvander(u, order)


@dataclass(frozen=True)
class AxisCorrection:
    """A fitted correction ``f = g(phi)`` and its uncertainty budget.

    Attributes
    ----------
    order : int
        Legendre order ``K`` chosen.
    coefficients_hz : ndarray, shape (K + 1,)
        Legendre coefficients of ``g - reference_hz`` in ``u = (phi - phase_center_rad) /
        phase_half_rad`` (Hz).
    reference_hz : float
        The mean of the lines' target frequencies (Hz).
    phase_center_rad, phase_half_rad : float
        Centre and half range of the lines' phases (rad).
    labels : tuple of str
        The lines used, in the order of ``line_phase_rad``.
    line_phase_rad : ndarray, shape (M,)
        The meter's phase at each line (rad).
    line_target_hz : ndarray, shape (M,)
        Each line's expected centre in the cell (Hz): table centre plus pressure shift.
    residual_hz : ndarray, shape (M,)
        ``line_target_hz - g(line_phase_rad)`` (Hz).
    chi2 : float
        Generalised chi-square of the fit with the stated covariance.
    order_scores : dict of int to float
        The information criterion of each order tried.
    model_std_hz : float
        The interpolation's model error (Hz), >= 0.
    term_covariance : dict of str to ndarray, shape (K + 1, K + 1)
        Covariance of the coefficients (Hz^2) due to each term of :data:`BUDGET_TERMS`
        (the model error excepted).
    """

    order: int
    coefficients_hz: np.ndarray
    reference_hz: float
    phase_center_rad: float
    phase_half_rad: float
    labels: tuple
    line_phase_rad: np.ndarray
    line_target_hz: np.ndarray
    residual_hz: np.ndarray
    chi2: float
    order_scores: dict
    model_std_hz: float
    term_covariance: dict = field(repr=False)

    def _u(self, phase_rad) -> np.ndarray:
        return (np.asarray(phase_rad, dtype=float) - self.phase_center_rad) / self.phase_half_rad

    def frequency_hz(self, phase_rad) -> np.ndarray:
        """Corrected frequency (Hz) at the meter's unwrapped phase (rad), shape of the input."""
        u = self._u(phase_rad)
        return self.reference_hz + np.polynomial.legendre.legval(u, self.coefficients_hz)

    def slope_hz_per_rad(self, phase_rad) -> np.ndarray:
        """``dg / dphi`` (Hz/rad): the local FSR over 2 pi."""
        derivative = np.polynomial.legendre.legder(self.coefficients_hz)
        return np.polynomial.legendre.legval(self._u(phase_rad), derivative) / self.phase_half_rad

    def budget_hz(self, phase_rad) -> dict:
        """Standard uncertainty (Hz) of ``g`` at phases (rad) by term, and ``"total"``
        (the terms in quadrature); each an array of the input's shape."""
        u = np.atleast_1d(self._u(phase_rad))
        rows = _basis(u.reshape(-1), self.order)
        budget = {}
        for name, covariance in self.term_covariance.items():
            variance = np.einsum("ij,jk,ik->i", rows, covariance, rows)
            budget[name] = np.sqrt(np.maximum(variance, 0.0))
        budget["phase_interpolation"] = np.hypot(budget["phase_interpolation"], self.model_std_hz)
        budget["total"] = np.sqrt(sum(budget[name] ** 2 for name in BUDGET_TERMS))
        shape = np.shape(phase_rad)
        return {name: value.reshape(shape) for name, value in budget.items()}

    def inside(self, phase_rad) -> np.ndarray:
        """Whether each phase lies between the first and the last line (interpolated, not
        extrapolated)."""
        return np.abs(self._u(phase_rad)) <= 1.0


def _gls(design: np.ndarray, target: np.ndarray, weight: np.ndarray):
    normal = design.T @ weight @ design
    covariance = np.linalg.inv(normal)
    coefficients = covariance @ design.T @ weight @ target
    residual = target - design @ coefficients
    return coefficients, covariance, residual, float(residual @ weight @ residual)


def fit_axis_correction(
    line_phase_rad,
    lines: ReferenceLines,
    *,
    center_std_rad,
    phase_std_rad,
    pressure_pa: float | None = None,
    pressure_std_pa: float = 0.0,
    order: int | None = None,
    max_order: int = MAX_ORDER,
) -> AxisCorrection:
    """Fit the axis correction ``f = g(phi)`` to identified lines (module docstring).

    Parameters
    ----------
    line_phase_rad : array_like, shape (M,)
        The meter's unwrapped phase at each identified line centre (rad), ``M >= 2``.
    lines : ReferenceLines
        The identified table lines, one per phase, in the same order (``table.take``).
    center_std_rad : array_like, shape (M,)
        Standard error of each line centre from its fit (rad of phase).
    phase_std_rad : array_like, shape (M,)
        Standard error of the meter's (smoothed) phase at each line (rad).
    pressure_pa : None or float
        The cell's pressure (Pa); required when the table has pressure shifts.
    pressure_std_pa : float
        Its standard uncertainty (Pa).
    order : None or int
        Legendre order to use; None: chosen by the information criterion.
    max_order : int
        Highest order tried.

    Returns
    -------
    AxisCorrection

    Raises
    ------
    InputError
        For fewer than 2 lines, mismatched lengths, non-finite or non-positive
        uncertainties, or a table with pressure shifts and no pressure.
    """
    phase = np.asarray(line_phase_rad, dtype=float).reshape(-1)
    count = phase.size
    fit_std = np.asarray(center_std_rad, dtype=float).reshape(-1)
    smooth_std = np.asarray(phase_std_rad, dtype=float).reshape(-1)
    if count < 2 or len(lines) != count or fit_std.size != count or smooth_std.size != count:
        raise InputError(
            f"the axis correction needs at least 2 identified lines with one phase, one "
            f"centre error and one phase error each; got {count} phases for {len(lines)} lines"
        )
    if not (np.all(np.isfinite(phase)) and np.all(fit_std >= 0) and np.all(smooth_std >= 0)):
        raise InputError("line phases must be finite and their errors >= 0")
    if lines.pressure_shift_hz_per_pa is not None and pressure_pa is None:
        raise InputError(
            "the table gives zero-pressure centres with pressure shifts: give the cell's "
            "pressure_pa (and pressure_std_pa)",
            parameter="pressure_pa",
        )
    if not (np.isfinite(pressure_std_pa) and pressure_std_pa >= 0):
        raise InputError(f"pressure_std_pa must be >= 0, got {shown(pressure_std_pa)}")
    target = lines.centers_at(pressure_pa)
    reference = float(target.mean())
    center, half = 0.5 * (phase.max() + phase.min()), 0.5 * (phase.max() - phase.min())
    if not half > 0:
        raise InputError("the identified lines must lie at different phases")
    u = (phase - center) / half
    slope = np.polyfit(phase, target, 1)[0]
    shift = lines.pressure_shift_hz_per_pa
    terms = {
        "line_table": np.diag(lines.std_hz**2),
        "line_center_fit": np.diag((slope * fit_std) ** 2),
        "pressure_shift": (
            np.zeros((count, count))
            if shift is None
            else np.outer(shift, shift) * float(pressure_std_pa) ** 2
        ),
        "phase_interpolation": np.diag((slope * smooth_std) ** 2),
    }
    total = sum(terms.values())
    weight = np.linalg.inv(total)
    highest = min(int(max_order), count - 1)
    orders = range(1, highest + 1) if order is None else [int(order)]
    if order is not None and not 1 <= order <= count - 1:
        raise InputError(f"order must be 1 to {count - 1} for {count} lines, got {shown(order)}")
    scores, fits = {}, {}
    for k in orders:
        fits[k] = _gls(_basis(u, k), target - reference, weight)
        scores[k] = fits[k][3] + (k + 1) * np.log(count)
    chosen = min(scores, key=scores.get)
    coefficients, covariance, residual, chi2 = fits[chosen]
    design = _basis(u, chosen)
    gain = covariance @ design.T @ weight  # coefficients = gain @ targets
    term_covariance = {name: gain @ value @ gain.T for name, value in terms.items()}
    return AxisCorrection(
        order=chosen,
        coefficients_hz=coefficients,
        reference_hz=reference,
        phase_center_rad=float(center),
        phase_half_rad=float(half),
        labels=tuple(lines.labels),
        line_phase_rad=phase,
        line_target_hz=target,
        residual_hz=residual,
        chi2=chi2,
        order_scores=scores,
        model_std_hz=_model_std_hz(design, target - reference, total),
        term_covariance=term_covariance,
    )


def _model_std_hz(design: np.ndarray, target: np.ndarray, total: np.ndarray) -> float:
    """RMS of the leave-one-line-out residuals in excess of their expected standard
    deviation (Hz); 0 when they are explained (or too few lines to leave one out)."""
    count, parameters = design.shape
    if count <= parameters + 1:
        return 0.0
    excess = []
    for i in range(count):
        keep = np.arange(count) != i
        weight = np.linalg.inv(total[np.ix_(keep, keep)])
        coefficients, covariance, _, _ = _gls(design[keep], target[keep], weight)
        gain = design[i] @ covariance @ design[keep].T @ weight
        residual = target[i] - design[i] @ coefficients
        expected = total[i, i] + gain @ total[np.ix_(keep, keep)] @ gain
        expected -= 2.0 * gain @ total[keep, i]
        excess.append(residual**2 - expected)
    return float(np.sqrt(max(np.mean(excess), 0.0)))
