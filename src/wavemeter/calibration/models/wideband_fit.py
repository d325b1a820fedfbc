"""The wide-band model of the port powers and its fit: a phase polynomial and a smooth map.

With ``y = (f - f0) / h`` (``f0`` the middle of the band, ``h`` its half width) a reading
is ``p = m A(y) u(t(y)) (+ d)``, ``t(y) = sum_{i=1..P} b_i y^i``, ``A(y) = sum_{j=0..J} A_j
L_j(y)`` (Legendre polynomials; ``P = 1``, ``J = 0`` is the paper's model)
(:class:`BandModel`). :func:`fit_band_region` fits it by variable projection (the map
linear, the phase coefficients by Levenberg-Marquardt); :func:`fit_band` starts from the
paper's delay search within one FSR of the middle and grows outwards, doubling the radius
(``GROWTH``), so that sweeps with missing FSRs fit like dense ones.
:func:`band_frequency_hz` reads a frequency with a coarse value within half an FSR
(``PREDICT_ITERATIONS`` rounds of map, phase and Newton steps on the polynomial).

Theory (the band model, the fit, reading a frequency): the docs' wide-band page
(``docs/theory/wideband.rst``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre, polynomial
from scipy import linalg, optimize

from ...exceptions import InputError
from ...model.cone import cone_vectors, wrap_phase_rad

__all__ = [
    "BandFit",
    "BandModel",
    "GROWTH",
    "GROWTH_READINGS",
    "NEWTON_STEPS",
    "PREDICT_ITERATIONS",
    "band_frequency_hz",
    "band_object_derivatives",
    "band_objects",
    "band_phase_rad",
    "band_phase_slope",
    "check_monotonic",
    "evenly",
    "fit_band",
    "fit_band_region",
    "least_squares_map",
    "map_coefficients",
    "normal_factor",
    "padded",
    "rescaled",
]

#: each growth step of the fit multiplies the radius by this
GROWTH = 2.0
#: readings of a growth step, at most (evenly spaced over those in its radius)
GROWTH_READINGS = 4000
#: map evaluations per prediction: at the coarse frequency, then at the retrieved one
PREDICT_ITERATIONS = 3
#: Newton steps solving the phase polynomial for the frequency
NEWTON_STEPS = 5


# ---------------------------------------------------------------------- the model
def band_phase_rad(y, coefficients_rad) -> np.ndarray:
    """``t(y) = sum_i b_i y^i`` (rad) for ``b = coefficients_rad`` (P,), ``i = 1..P``."""
    return polynomial.polyval(np.asarray(y, dtype=float), np.concatenate([[0.0], coefficients_rad]))


def band_phase_slope(y, coefficients_rad) -> np.ndarray:
    """``dt / dy = sum_i i b_i y^(i-1)`` (rad per unit of ``y``)."""
    orders = np.arange(1, len(coefficients_rad) + 1)
    return polynomial.polyval(np.asarray(y, dtype=float), orders * np.asarray(coefficients_rad))


def band_objects(y, phase_rad, scale, map_order: int, affine: bool) -> np.ndarray:
    """Design columns ``X_k = L(y_k) (x) m_k u(t_k)`` (N, 3 (J + 1)), plus ones when
    ``affine``: column ``3 j + c`` is Legendre order ``j`` times cone component ``c``."""
    power = 1.0 if scale is None else scale
    cone = cone_vectors(phase_rad, power)
    basis = legendre.legvander(y, map_order)
    objects = (basis[:, :, None] * cone[:, None, :]).reshape(cone.shape[0], -1)
    if affine:
        objects = np.column_stack([objects, np.ones(cone.shape[0])])
    return objects


def band_object_derivatives(y, phase_rad, scale, map_order: int, affine: bool, phase_order: int):
    """``dX / db_i`` (P, N, q) of :func:`band_objects` by the phase coefficients:
    ``L(y) (x) m u'(t)`` times ``dt / db_i = y^i``."""
    power = 1.0 if scale is None else np.asarray(scale, dtype=float)
    tangent = np.zeros((phase_rad.size, 3))
    tangent[:, 0], tangent[:, 1] = -np.sin(phase_rad), np.cos(phase_rad)
    tangent *= np.broadcast_to(power, phase_rad.shape)[:, None]
    basis = legendre.legvander(y, map_order)
    moved = (basis[:, :, None] * tangent[:, None, :]).reshape(phase_rad.size, -1)
    if affine:
        moved = np.column_stack([moved, np.zeros(phase_rad.size)])
    powers_of_y = np.power.outer(y, np.arange(1, phase_order + 1)).T
    return powers_of_y[:, :, None] * moved[None]


def map_coefficients(matrix: np.ndarray, map_order: int) -> tuple[np.ndarray, np.ndarray | None]:
    """Split least-squares coefficients (q, n) into the Legendre map coefficients
    ``A_j`` (J + 1, n, 3) (W) and the offsets (n,) (W; None without the ones column)."""
    blocks = 3 * (map_order + 1)
    coefficients = matrix[:blocks].reshape(map_order + 1, 3, -1).transpose(0, 2, 1)
    offsets = matrix[blocks].copy() if matrix.shape[0] > blocks else None
    return np.ascontiguousarray(coefficients), offsets


@dataclass(frozen=True)
class BandModel:
    """A fitted wide-band model, enough to read frequencies.

    Attributes
    ----------
    center_hz, half_span_hz : float
        ``f0`` and ``h`` (Hz): ``y = (f - f0) / h``.
    phase_coefficients_rad : ndarray, shape (P,)
        ``b_1..b_P`` (rad): ``t(y) = sum b_i y^i``.
    map_coefficients_w : ndarray, shape (J + 1, n, 3)
        Legendre coefficients ``A_j`` of the map (W).
    """

    center_hz: float
    half_span_hz: float
    phase_coefficients_rad: np.ndarray
    map_coefficients_w: np.ndarray

    def normalized(self, frequency_hz) -> np.ndarray:
        """``y = (f - f0) / h`` of frequencies (Hz)."""
        return (np.asarray(frequency_hz, dtype=float) - self.center_hz) / self.half_span_hz

    def phase_rad(self, frequency_hz) -> np.ndarray:
        """The model phase ``t`` (rad, not wrapped) at frequencies (Hz)."""
        return band_phase_rad(self.normalized(frequency_hz), self.phase_coefficients_rad)

    def phase_slope_rad_per_hz(self, frequency_hz) -> np.ndarray:
        """``dt / df`` (rad/Hz): ``2 pi`` times the local group delay; ``2 pi / (dt/df)`` is
        the local FSR."""
        slope = band_phase_slope(self.normalized(frequency_hz), self.phase_coefficients_rad)
        return slope / self.half_span_hz

    def maps_at(self, frequency_hz) -> np.ndarray:
        """The map ``A(f)`` (N, n, 3) (W) at each frequency (N,) (Hz)."""
        coefficients = self.map_coefficients_w
        basis = legendre.legvander(self.normalized(frequency_hz), coefficients.shape[0] - 1)
        return np.einsum("kj,jnc->knc", basis, coefficients)

    def frequency_of_phase_hz(self, phase_rad, start_hz) -> np.ndarray:
        """The frequency (Hz) whose model phase is ``phase_rad`` (rad, unwrapped), by Newton
        steps from ``start_hz`` (the phase rises monotonically across the band)."""
        y = self.normalized(start_hz)
        coefficients = self.phase_coefficients_rad
        for _ in range(NEWTON_STEPS):
            y = y - (band_phase_rad(y, coefficients) - phase_rad) / band_phase_slope(
                y, coefficients
            )
        return self.center_hz + y * self.half_span_hz


def band_frequency_hz(
    model: BandModel,
    readings: np.ndarray,
    coarse_hz: np.ndarray,
    retrieve: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequency (Hz) of readings: the fringe order nearest ``coarse_hz``.

    Parameters
    ----------
    model : BandModel
    readings : ndarray, shape (N, n)
        Offset-corrected readings (W).
    coarse_hz : ndarray, shape (N,)
        Approximate frequency of each reading (Hz), within half a local FSR.
    retrieve : callable
        ``retrieve(readings (N, n), maps (N, n, 3)) -> phase (N,)`` (rad): the phase of
        each reading under its own map.

    Returns
    -------
    frequency_hz : ndarray, shape (N,)
    phase_rad : ndarray, shape (N,)
        The retrieved phase (rad, wrapped) at the last map evaluation.
    maps : ndarray, shape (N, n, 3)
        The map at the returned frequency's previous estimate (W).
    """
    reference = model.phase_rad(coarse_hz)
    frequency = np.asarray(coarse_hz, dtype=float)
    for _ in range(PREDICT_ITERATIONS):
        maps = model.maps_at(frequency)
        phase = retrieve(readings, maps)
        target = reference + wrap_phase_rad(phase - reference)
        frequency = model.frequency_of_phase_hz(target, frequency)
    return frequency, phase, maps


# ---------------------------------------------------------------------- the fit
@dataclass(frozen=True)
class BandFit:
    """Outcome of :func:`fit_band_region` (in its coordinate ``z = (f - f0) / radius``).

    Attributes
    ----------
    coefficients_rad : ndarray, shape (P,)
        Phase coefficients ``a_i`` of ``t = sum a_i z^i`` (rad).
    matrix : ndarray, shape (q, n)
        Least-squares coefficients of the design columns (W).
    cost : float
        ``J = mean_k ||p_k - X_k M||^2`` (W^2).
    phase_rad : ndarray, shape (N,)
        Model phase of every reading.
    residual_w : ndarray, shape (N, n)
        Readings minus the fitted model (W).
    gauge : ndarray, shape (n, 3), or None
        The rotation held out of the map's order-1 coefficient (:func:`fit_band_region`),
        or None.
    """

    coefficients_rad: np.ndarray
    matrix: np.ndarray
    cost: float
    phase_rad: np.ndarray
    residual_w: np.ndarray
    gauge: np.ndarray | None = None


def fit_band_region(
    powers,
    frequency_hz,
    center_hz: float,
    radius_hz: float,
    start_rad,
    *,
    map_order: int,
    scale=None,
    affine: bool = False,
    gauge=None,
) -> BandFit:
    """Variable-projection fit of the phase coefficients in ``z = (f - f0) / radius``.

    Parameters
    ----------
    powers : ndarray, shape (N, n)
        Readings (W), dark-subtracted.
    frequency_hz : ndarray, shape (N,)
        Known frequencies (Hz).
    center_hz, radius_hz : float
        ``f0`` and the radius (Hz) of the coordinate ``z``.
    start_rad : array_like, shape (P,)
        Starting phase coefficients in ``z`` (rad).
    map_order : int
        Legendre order ``J`` of the map in ``z``.
    scale : None or ndarray, shape (N,)
        Relative monitored source power per reading.
    affine : bool
        Fit per-port offsets too (a column of ones).
    gauge : None or ndarray, shape (n, 3)
        The rotation about the cone axis of a constant map ``A_0`` (``A_0 G``, ``G`` the
        quarter turn's generator: ``[A_0[:, 1], -A_0[:, 0], 0]``), held out of the map's
        order-1 coefficient ``A_1`` (``<A_1, A_0 G> = 0``): a map's slope that rotates the
        fringe is the phase's slope to first order, and a sweep of one or two FSRs cannot
        tell them apart; the phase then carries all of the fringe's rotation. None: no
        constraint (``map_order`` >= 1 when given).

    Returns
    -------
    BandFit
    """
    z = (frequency_hz - center_hz) / radius_hz
    order = len(start_rad)
    constraint = None
    if gauge is not None:
        rows = 3 * (map_order + 1) + (1 if affine else 0)
        constraint = np.zeros((rows, powers.shape[1]))
        constraint[3:6] = np.asarray(gauge, dtype=float).T

    def held(factor, right):
        """Least squares ``(X'X)^-1 right`` under the constraint (one Lagrange multiplier
        shared by the ports)."""
        matrix = linalg.cho_solve(factor, right, check_finite=False)
        if constraint is None:
            return matrix
        moved = linalg.cho_solve(factor, constraint, check_finite=False)
        return matrix - moved * (np.vdot(constraint, matrix) / np.vdot(constraint, moved))

    solved: dict[bytes, tuple] = {}

    def solve(coefficients):
        # the residual and the Jacobian are asked at the same point: one QR for both
        key = np.asarray(coefficients, dtype=float).tobytes()
        if key not in solved:
            phase = band_phase_rad(z, coefficients)
            objects = band_objects(z, phase, scale, map_order, affine)
            factor = normal_factor(objects)
            matrix = held(factor, objects.T @ powers)
            solved.clear()
            solved[key] = (phase, objects, factor, matrix)
        return solved[key]

    def residual(coefficients):
        _, objects, _, matrix = solve(coefficients)
        return (powers - objects @ matrix).ravel()

    def jacobian(coefficients):
        phase, objects, factor, matrix = solve(coefficients)
        moved = band_object_derivatives(z, phase, scale, map_order, affine, order)
        columns = []
        for derivative in moved:
            image = derivative @ matrix
            inside = objects @ held(factor, objects.T @ image)
            columns.append(-(image - inside).ravel())
        return np.column_stack(columns)

    start = np.asarray(start_rad, dtype=float)
    result = optimize.least_squares(
        residual, start, jac=jacobian, method="lm", x_scale="jac", xtol=1e-13, ftol=1e-13
    )
    phase, objects, _, matrix = solve(result.x)
    error = powers - objects @ matrix
    return BandFit(
        coefficients_rad=result.x,
        matrix=matrix,
        cost=float(np.einsum("ij,ij->", error, error) / powers.shape[0]),
        phase_rad=phase,
        residual_w=error,
        gauge=None if constraint is None else constraint[3:6].T.copy(),
    )


def normal_factor(objects: np.ndarray):
    """Cholesky factor of ``X' X`` (for ``scipy.linalg.cho_solve``). The columns are cone
    components times Legendre polynomials, nearly orthogonal over a sweep: the normal
    equations lose nothing a QR would keep, at a fraction of its cost."""
    try:
        return linalg.cho_factor(objects.T @ objects, check_finite=False)
    except linalg.LinAlgError as exc:
        raise InputError(
            "the calibration sweep does not determine the wide-band map (its design is "
            "singular): too few readings or FSRs for the map order; lower map_order or sweep "
            "more of the band",
            parameter="map_order",
        ) from exc


def least_squares_map(objects: np.ndarray, powers: np.ndarray) -> np.ndarray:
    """Least-squares coefficients (q, n) of readings (N, n) on design columns (N, q)."""
    return linalg.cho_solve(normal_factor(objects), objects.T @ powers, check_finite=False)


def rescaled(coefficients_rad, factor: float) -> np.ndarray:
    """Phase coefficients in a coordinate whose unit is ``factor`` times larger:
    ``t = sum a_i z^i`` with ``z = factor z'`` is ``sum a_i factor^i z'^i``."""
    orders = np.arange(1, len(coefficients_rad) + 1)
    return np.asarray(coefficients_rad, dtype=float) * float(factor) ** orders


def padded(coefficients_rad, order: int) -> np.ndarray:
    """The first ``order`` coefficients, with zeros appended when there are fewer."""
    values = np.zeros(order)
    count = min(order, len(coefficients_rad))
    values[:count] = coefficients_rad[:count]
    return values


def evenly(rows: np.ndarray, count: int) -> np.ndarray:
    """At most ``count`` of the indices ``rows``, evenly spaced along them."""
    if rows.size <= count:
        return rows
    return rows[np.unique(np.linspace(0, rows.size - 1, count).astype(int))]


def fit_band(
    powers,
    frequency_hz,
    center_hz: float,
    half_span_hz: float,
    start_delay_s: float,
    start_radius_hz: float,
    *,
    phase_order: int,
    scale=None,
    affine: bool = False,
    readings: int | None = GROWTH_READINGS,
) -> np.ndarray:
    """Phase coefficients ``b`` (P,) (rad, in ``y``) grown from a local delay to the band.

    Starting from ``t = 2 pi (f - f0) tau`` on the readings within ``start_radius_hz`` of
    ``f0`` (where ``tau = start_delay_s`` was found), each step fits the readings within
    a radius with one constant map and doubles it, up to the half span (module docstring).

    Parameters
    ----------
    powers, frequency_hz, scale, affine
        As for :func:`fit_band_region`.
    center_hz, half_span_hz : float
        ``f0`` and ``h`` (Hz).
    start_delay_s, start_radius_hz : float
        The delay (s) found on the readings within ``start_radius_hz`` (Hz) of ``f0``.
    phase_order : int
        ``P``.
    readings : int or None
        Readings per growth step, at most (None: all).

    Returns
    -------
    ndarray, shape (P,), rad
    """
    distance = np.abs(frequency_hz - center_hz)
    radius = min(max(start_radius_hz, np.finfo(float).tiny), half_span_hz)
    coefficients = padded([2.0 * np.pi * radius * start_delay_s], phase_order)
    while True:
        rows = np.flatnonzero(distance <= radius * (1.0 + 1e-12))
        if readings is not None:
            rows = evenly(rows, readings)
        fit = fit_band_region(
            powers[rows],
            frequency_hz[rows],
            center_hz,
            radius,
            coefficients,
            map_order=0,
            scale=None if scale is None else scale[rows],
            affine=affine,
        )
        if radius >= half_span_hz:
            return fit.coefficients_rad
        grown = min(GROWTH * radius, half_span_hz)
        coefficients = rescaled(fit.coefficients_rad, grown / radius)
        radius = grown


def check_monotonic(model: BandModel) -> None:
    """Raise when the fitted phase does not rise across the band (no frequency then
    belongs to one phase)."""
    y = np.linspace(-1.0, 1.0, 2001)
    slope = band_phase_slope(y, model.phase_coefficients_rad)
    if np.any(slope <= 0):
        raise InputError(
            "the fitted phase polynomial does not rise monotonically across the band (its "
            f"slope changes sign near y = {y[np.argmax(slope <= 0)]:.3g}): the phase order is "
            "too high for the sweep; set a lower phase_order or sweep more of the band",
            parameter="phase_order",
        )
