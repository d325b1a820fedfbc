"""The thermal model of the port powers and its fit: one map, a bias phase and a delay that
move with temperature.

With ``dT = T - T0`` (``T0`` the mean calibration temperature) a reading at frequency ``f``
and chip temperature ``T`` is ``p = A u(t)``, ``t = 2 pi (f - f0) tau0 (1 + beta dT) +
alpha dT``: one map ``A`` (n, 3), the delay ``tau0`` at ``T0``, the bias phase rate
``alpha`` (rad/K) and the relative delay rate ``beta`` (1/K) (:func:`thermal_phase_rad`).
:func:`fit_thermal_map` fits it by variable projection: a grid over ``(tau0, alpha)`` on at
most ``GRID_READINGS`` readings, then Levenberg-Marquardt on all readings over all three.
:func:`temperature_layout` finds what the temperatures can tell (clusters, the bias rates
they resolve, the effective spread left after a line in frequency) and
:func:`spread_error` says what is missing when it is too little (``MIN_SPREAD_STD``).

Theory (the model, the fit, what the temperatures can tell): the docs' thermal page
(``docs/theory/thermal.rst``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize

from ...exceptions import InputError
from ...model.cone import cone_vectors
from .delay_search import bracket_grid, frequency_text

__all__ = [
    "CLUSTER_GAP_FRACTION",
    "CLUSTER_GAP_STD",
    "MIN_SPREAD_STD",
    "PLAUSIBLE_FRINGE_SHIFT_HZ_PER_K",
    "TemperatureLayout",
    "ThermalFit",
    "fit_thermal_map",
    "phase_derivatives",
    "spread_error",
    "temperature_layout",
    "thermal_objects",
    "thermal_phase_rad",
]

#: largest fringe shift (Hz per kelvin) a chip is expected to have: SOI moves 7.5-11 GHz/K
PLAUSIBLE_FRINGE_SHIFT_HZ_PER_K = 15e9
#: the bias rates searched reach this multiple of the plausible one (when resolvable)
RATE_SEARCH_FACTOR = 2.0
#: a gap between calibration temperatures larger than this many sensor std ...
CLUSTER_GAP_STD = 10.0
#: ... and than this fraction of their range separates clusters
CLUSTER_GAP_FRACTION = 0.02
#: the effective temperature spread (std, K) must reach this many sensor std
MIN_SPREAD_STD = 10.0
#: readings the grid stage of the fit uses, at most (evenly spaced in acquisition order)
GRID_READINGS = 4000
#: ... fewer when the bias-rate grid is long: at most this many trial phases per delay ...
GRID_CELLS = 2_000_000
#: ... but never fewer readings than this
MIN_GRID_READINGS = 500
#: bias-rate grid step times the temperature range (rad): a phase error of 1/4 rad
RATE_GRID_STEP_RAD = 0.25
#: bias-rate grid points, at most
MAX_RATE_POINTS = 4096


# ---------------------------------------------------------------------- the model
def thermal_phase_rad(
    frequency_hz,
    temperature_k,
    center_hz: float,
    reference_temperature_k: float,
    delay_s: float,
    phase_rate_rad_per_k: float,
    delay_rate_per_k: float,
) -> np.ndarray:
    """Object phase ``t = 2 pi (f - f0) tau0 (1 + beta dT) + alpha dT`` (rad).

    Parameters
    ----------
    frequency_hz, temperature_k : array_like, shape (N,)
        Source frequency (Hz) and chip temperature (K) of each reading.
    center_hz, reference_temperature_k : float
        ``f0`` (Hz) and ``T0`` (K).
    delay_s, phase_rate_rad_per_k, delay_rate_per_k : float
        ``tau0`` (s), ``alpha`` (rad/K), ``beta`` (1/K).

    Returns
    -------
    ndarray, shape (N,), rad
    """
    offset = np.asarray(temperature_k, dtype=float) - reference_temperature_k
    detuning = 2.0 * np.pi * (np.asarray(frequency_hz, dtype=float) - center_hz)
    return detuning * delay_s * (1.0 + delay_rate_per_k * offset) + phase_rate_rad_per_k * offset


def phase_derivatives(frequency_hz, temperature_k, center_hz, reference_k, theta) -> np.ndarray:
    """``dt / dtheta`` (3, N): by ``tau0`` (rad/s), ``alpha`` (K), ``beta`` (rad K)."""
    delay, _, delay_rate = theta
    offset = temperature_k - reference_k
    detuning = 2.0 * np.pi * (frequency_hz - center_hz)
    return np.stack(
        [detuning * (1.0 + delay_rate * offset), offset, detuning * delay * offset], axis=0
    )


def thermal_objects(
    phase_rad, scale=None, affine: bool = False, derivatives=None
) -> tuple[np.ndarray, np.ndarray | None]:
    """Object vectors (N, k) at phases ``t`` and, given ``dt / dtheta`` (q, N), their
    derivatives (q, N, k); ``k`` = 3, or 4 with a column of ones when ``affine``.

    ``x = m [cos t, sin t, sqrt 2]`` (``m`` the relative monitored power or 1) gives
    ``dx / dtheta = m [-sin t, cos t, 0] dt / dtheta``.
    """
    power = 1.0 if scale is None else np.asarray(scale, dtype=float)
    objects = cone_vectors(phase_rad, power)
    if affine:
        objects = np.column_stack([objects, np.ones(objects.shape[0])])
    if derivatives is None:
        return objects, None
    tangent = np.zeros_like(objects)
    tangent[:, 0], tangent[:, 1] = -np.sin(phase_rad), np.cos(phase_rad)
    tangent *= np.broadcast_to(power, phase_rad.shape)[:, None]
    return objects, np.asarray(derivatives)[:, :, None] * tangent[None]


# ---------------------------------------------------------------------- the temperatures
@dataclass(frozen=True)
class TemperatureLayout:
    """What the calibration temperatures can tell about the thermal rates.

    Attributes
    ----------
    reference_k : float
        ``T0``: the mean calibration temperature (K).
    range_k : (float, float)
        Lowest and highest calibration temperature (K).
    clusters_k : tuple of float
        Mean temperature of each cluster (K); one cluster for a continuous recording.
    smallest_step_k : float or None
        Smallest step between adjacent clusters (K); None with one cluster.
    unambiguous_rad_per_k : float or None
        ``pi / smallest_step_k``: the bias rate is resolved within +- this (rad/K).
    searched_rad_per_k : float
        Half width of the bias rates searched (rad/K).
    plausible_rad_per_k : float
        Half width a chip's bias rate may have at the design FSR (rad/K).
    spread_k : float
        Standard deviation of the calibration temperatures (K).
    effective_spread_k : float
        Their standard deviation left after a least-squares line in frequency (K).
    largest_cluster : ndarray of bool, shape (N,)
        Readings of the most populated cluster.
    """

    reference_k: float
    range_k: tuple[float, float]
    clusters_k: tuple[float, ...]
    smallest_step_k: float | None
    unambiguous_rad_per_k: float | None
    searched_rad_per_k: float
    plausible_rad_per_k: float
    spread_k: float
    effective_spread_k: float
    largest_cluster: np.ndarray

    def record(self) -> dict:
        """JSON-ready entries of ``diagnostics_["thermal"]``."""
        return {
            "reference_temperature_k": self.reference_k,
            "temperature_range_k": list(self.range_k),
            "temperatures_k": list(self.clusters_k),
            "smallest_step_k": self.smallest_step_k,
            "unambiguous_phase_rate_rad_per_k": self.unambiguous_rad_per_k,
            "searched_phase_rate_rad_per_k": self.searched_rad_per_k,
            "plausible_phase_rate_rad_per_k": self.plausible_rad_per_k,
            "spread_k": self.spread_k,
            "effective_spread_k": self.effective_spread_k,
        }


def spread_error(layout_spread_k: float, effective_k: float, needed_k: float, why: str):
    """The InputError for temperatures that cannot separate the thermal rates; ``why``
    says what sets the ``needed_k`` standard deviation."""
    if layout_spread_k >= needed_k > effective_k:
        return InputError(
            f"the calibration temperature changes together with the frequency: of its "
            f"spread (std {layout_spread_k:.3g} K) only {effective_k:.3g} K is not a straight "
            f"line in frequency, so the bias rate cannot be told from the delay "
            f"({needed_k:.3g} K needed: {why}); record sweeps at two or more temperatures, "
            "or sweep the laser repeatedly (up and down) while the temperature changes",
            parameter="temperature_k",
        )
    return InputError(
        f"the calibration temperatures spread too little to fit the thermal rates: their "
        f"standard deviation is {effective_k:.3g} K, and {needed_k:.3g} K is needed ({why}); "
        f"spread the calibration temperatures that much (e.g. two sweeps "
        f"{2 * needed_k:.3g} K apart, or more sweeps over a wider range)",
        parameter="temperature_k",
    )


def temperature_layout(
    frequency_hz, temperature_k, *, sensor_std_k: float, fsr_hz: float
) -> TemperatureLayout:
    """Clusters, steps and spread of the calibration temperatures.

    Parameters
    ----------
    frequency_hz, temperature_k : ndarray, shape (N,)
        Known frequency (Hz) and chip temperature (K) of each calibration reading.
    sensor_std_k : float
        Standard deviation of the temperature sensor (K).
    fsr_hz : float
        Design FSR (Hz), for the plausible bias rate.

    Returns
    -------
    TemperatureLayout

    Raises
    ------
    InputError
        ``parameter="temperature_k"``: the effective spread is below ``MIN_SPREAD_STD``
        sensor standard deviations (all temperatures equal, or collinear with frequency).
    """
    order = np.argsort(temperature_k, kind="stable")
    ordered = temperature_k[order]
    smallest_gap = max(CLUSTER_GAP_STD * sensor_std_k, CLUSTER_GAP_FRACTION * np.ptp(ordered))
    gaps = np.flatnonzero(np.diff(ordered) > smallest_gap)
    members = np.split(order, gaps + 1)
    centres = np.array([temperature_k[group].mean() for group in members])
    largest = np.zeros(temperature_k.size, dtype=bool)
    largest[max(members, key=len)] = True
    step = float(np.diff(centres).min()) if centres.size > 1 else None
    plausible = 2.0 * np.pi * PLAUSIBLE_FRINGE_SHIFT_HZ_PER_K / fsr_hz
    unambiguous = None if step is None else float(np.pi / step)
    searched = RATE_SEARCH_FACTOR * plausible
    if unambiguous is not None:
        searched = min(searched, unambiguous)
    design = np.column_stack([np.ones_like(frequency_hz), frequency_hz - frequency_hz.mean()])
    line = design @ linalg.lstsq(design, temperature_k)[0]
    spread = float(np.std(temperature_k))
    effective = float(np.std(temperature_k - line))
    needed = MIN_SPREAD_STD * sensor_std_k
    if effective < needed:
        raise spread_error(
            spread,
            effective,
            needed,
            f"{MIN_SPREAD_STD:g} x the temperature sensor's {sensor_std_k:g} K standard deviation",
        )
    return TemperatureLayout(
        reference_k=float(temperature_k.mean()),
        range_k=(float(ordered[0]), float(ordered[-1])),
        clusters_k=tuple(float(centre) for centre in centres),
        smallest_step_k=step,
        unambiguous_rad_per_k=unambiguous,
        searched_rad_per_k=float(searched),
        plausible_rad_per_k=float(plausible),
        spread_k=spread,
        effective_spread_k=effective,
        largest_cluster=largest,
    )


# ---------------------------------------------------------------------- the fit
@dataclass(frozen=True)
class ThermalFit:
    """Outcome of :func:`fit_thermal_map`.

    Attributes
    ----------
    theta : ndarray, shape (3,)
        ``(tau0 (s), alpha (rad/K), beta (1/K))``.
    map_ : ndarray, shape (n, 3) or (n, 4)
        Least-squares map at ``theta`` (W); with ``affine`` a fourth column of offsets.
    cost : float
        ``J = mean_k ||p_k - A x_k||^2`` (W^2).
    phase_rad : ndarray, shape (N,)
        Object phase of every reading at ``theta``.
    residual_w : ndarray, shape (N, n)
        Readings minus the fitted model (W).
    """

    theta: np.ndarray
    map_: np.ndarray
    cost: float
    phase_rad: np.ndarray
    residual_w: np.ndarray


def _grid_costs(powers, phases, scale, affine) -> np.ndarray:
    """Cost ``J`` (W^2) of the least-squares map for each row of trial phases (R, M), from
    the normal equations (accurate enough to rank the trials)."""
    power = 1.0 if scale is None else scale
    cosine, sine = np.cos(phases) * power, np.sin(phases) * power
    axis = np.sqrt(2.0) * power
    columns = [cosine, sine, np.broadcast_to(axis, cosine.shape)]
    if affine:
        columns.append(np.ones_like(cosine))
    k = len(columns)
    gram = np.empty((phases.shape[0], k, k))
    for row in range(k):
        for col in range(row, k):
            gram[:, row, col] = gram[:, col, row] = np.einsum(
                "rm,rm->r", columns[row], columns[col]
            )
    projections = np.stack([column @ powers for column in columns], axis=1)
    solution = np.linalg.solve(gram, projections)
    explained = np.einsum("rkn,rkn->r", projections, solution)
    return (np.einsum("mn,mn->", powers, powers) - explained) / powers.shape[0]


def fit_thermal_map(
    powers,
    frequency_hz,
    temperature_k,
    center_hz: float,
    layout: TemperatureLayout,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    scale=None,
    affine: bool = False,
) -> ThermalFit:
    """Fit one map and ``theta = (tau0, alpha, beta)`` to readings at many temperatures.

    Parameters
    ----------
    powers : ndarray, shape (N, n)
        Validated calibration readings (W), dark-subtracted.
    frequency_hz, temperature_k : ndarray, shape (N,)
        Known frequency (Hz) and chip temperature (K) of each reading.
    center_hz : float
        ``f0`` (Hz).
    layout : TemperatureLayout
        :func:`temperature_layout` of the temperatures (``T0``, the rates to search).
    fsr_hz, fsr_tolerance : float
        Design FSR (Hz) and the relative half width of the delay bracket.
    scale : None or ndarray, shape (N,)
        Relative monitored source power per reading.
    affine : bool
        Fit per-port offsets too (a fourth map column).

    Returns
    -------
    ThermalFit

    Raises
    ------
    InputError
        ``parameter="fsr_hz"`` when the best delay lies outside the bracket searched.
    """
    reference = layout.reference_k
    offset = temperature_k - reference
    detuning = 2.0 * np.pi * (frequency_hz - center_hz)
    # 1. grid over (tau0, alpha) at beta = 0 on evenly spaced readings
    relative = bracket_grid(fsr_hz, fsr_tolerance, float(np.ptp(frequency_hz)))
    temperature_range = max(float(np.ptp(temperature_k)), np.finfo(float).tiny)
    points = int(
        min(
            MAX_RATE_POINTS,
            np.ceil(2 * layout.searched_rad_per_k * temperature_range / RATE_GRID_STEP_RAD) + 1,
        )
    )
    # at most GRID_CELLS trial phases per trial delay bound the memory
    readings = max(min(GRID_READINGS, GRID_CELLS // points), MIN_GRID_READINGS)
    rows = np.unique(np.linspace(0, powers.shape[0] - 1, readings).astype(int))
    rates = np.linspace(-layout.searched_rad_per_k, layout.searched_rad_per_k, points)
    grid_scale = None if scale is None else scale[rows]
    best = (np.inf, 0.0, 0.0)
    for u in relative:
        phases = (detuning[rows] * (u / fsr_hz))[None, :] + rates[:, None] * offset[rows][None, :]
        costs = _grid_costs(powers[rows], phases, grid_scale, affine)
        index = int(np.argmin(costs))
        if costs[index] < best[0]:
            best = (float(costs[index]), u / fsr_hz, float(rates[index]))

    # 2. Levenberg-Marquardt on every reading over (tau0, alpha, beta)
    units = np.array([1.0 / fsr_hz, 1.0, 1e-5])

    def solve(theta):
        phase = thermal_phase_rad(frequency_hz, temperature_k, center_hz, reference, *theta)
        derivatives = phase_derivatives(frequency_hz, temperature_k, center_hz, reference, theta)
        objects, moved = thermal_objects(phase, scale, affine, derivatives)
        basis, triangle = linalg.qr(objects, mode="economic", check_finite=False)
        matrix = linalg.solve_triangular(triangle, basis.T @ powers, check_finite=False).T
        return phase, objects, moved, basis, matrix

    def residual(scaled):
        _, objects, _, _, matrix = solve(scaled * units)
        return (powers - objects @ matrix.T).ravel()

    def jacobian(scaled):
        _, _, moved, basis, matrix = solve(scaled * units)
        columns = []
        for derivative, unit in zip(moved, units, strict=True):
            image = derivative @ matrix.T
            columns.append(-(image - basis @ (basis.T @ image)).ravel() * unit)
        return np.column_stack(columns)

    start = np.array([best[1], best[2], 0.0]) / units
    result = optimize.least_squares(residual, start, jac=jacobian, method="lm", xtol=1e-12)
    theta = result.x * units
    low, high = fsr_hz * (1.0 - fsr_tolerance), fsr_hz * (1.0 + fsr_tolerance)
    if not low <= 1.0 / theta[0] <= high:
        raise InputError(
            f"the best thermal fit has an FSR of {frequency_text(1.0 / theta[0])}, outside the "
            f"bracket searched ({frequency_text(low)} to {frequency_text(high)}): set fsr_hz "
            "closer to the chip's FSR or widen fsr_tolerance",
            parameter="fsr_hz",
        )
    phase, objects, _, _, matrix = solve(theta)
    error = powers - objects @ matrix.T
    return ThermalFit(
        theta=theta,
        map_=matrix,
        cost=float(np.einsum("ij,ij->", error, error) / powers.shape[0]),
        phase_rad=phase,
        residual_w=error,
    )
