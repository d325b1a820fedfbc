"""The orders of the wide-band model, chosen by cross-validation on held-out whole FSRs.

:func:`select_orders` groups the sweep by FSR window (:func:`fsr_windows`), keeps the two
outermost windows in training and deals the others into ``CV_FOLDS`` folds; from the
paper's model ``(1, 0)`` it steps to the candidate one order higher in phase or in map
that lowers the held-out error significantly (``CV_Z`` standard errors), and stops where
more parameters no longer predict held-out FSRs better. Every candidate scored is kept in
the :class:`OrderSelection` (the cross-validation curve). :func:`raise_orders` then raises
the orders while the whole sweep rejects the smaller model by a nested F test at the
diagnostics' level; a map order stays below the number of windows minus one
(:func:`highest_map_order`).

Theory (the folds, the search, why the orders are raised): the docs' wide-band page
(``docs/theory/wideband.rst``, "Choosing the orders").
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import linalg, stats

from ...stats.nested_tests import TEST_P_VALUE
from .wideband_fit import (
    BandFit,
    BandModel,
    band_frequency_hz,
    band_object_derivatives,
    band_objects,
    band_phase_rad,
    evenly,
    fit_band_region,
    least_squares_map,
    map_coefficients,
    normal_factor,
    padded,
)

__all__ = [
    "CV_FOLDS",
    "CV_READINGS",
    "CV_Z",
    "MAX_MAP_ORDER",
    "MAX_PHASE_ORDER",
    "MIN_CV_WINDOWS",
    "OrderSelection",
    "fsr_windows",
    "parameter_count",
    "highest_map_order",
    "window_count",
    "raise_orders",
    "select_orders",
]

#: highest phase order and map order searched
MAX_PHASE_ORDER = 4
MAX_MAP_ORDER = 8
#: folds of held-out FSR windows
CV_FOLDS = 3
#: readings the cross-validation uses, at most (evenly spaced in acquisition order)
CV_READINGS = 20000
#: a higher order is taken when it lowers the held-out error by this many standard errors
CV_Z = 3.0
#: relative resolution of float64 arithmetic on the model (64 ulp): improvements below it,
#: in the frequencies held out or in the powers fitted, are rounding, not evidence (a
#: noiseless sweep keeps the orders its model has)
ROUNDING_RESOLUTION = 64 * float(np.finfo(float).eps)
#: FSR windows a sweep needs for the orders to be chosen (else the paper's (1, 0))
MIN_CV_WINDOWS = 2 + CV_FOLDS


def fsr_windows(frequency_hz, low_hz: float, fsr_hz: float) -> np.ndarray:
    """Index of the FSR-wide window of each frequency (Hz), counted from ``low_hz``."""
    return np.floor((np.asarray(frequency_hz, dtype=float) - low_hz) / fsr_hz).astype(int)


def window_count(frequency_hz, fsr_hz: float) -> int:
    """FSRs the sweep covers: its runs of readings (split where no reading falls for half
    an FSR) each count their span in FSRs, rounded, and at least one."""
    distinct = np.unique(np.asarray(frequency_hz, dtype=float))
    breaks = np.flatnonzero(np.diff(distinct) > 0.5 * fsr_hz)
    runs = np.split(distinct, breaks + 1)
    return int(sum(max(round(float(np.ptp(run)) / fsr_hz), 1) for run in runs))


def parameter_count(ports: int, phase_order: int, map_order: int, affine: bool) -> int:
    """Fitted numbers: ``3 n (J + 1)`` map coefficients, ``n`` offsets if fitted, ``P``."""
    return 3 * ports * (map_order + 1) + (ports if affine else 0) + phase_order


@dataclass(frozen=True)
class OrderSelection:
    """The orders and how they were chosen.

    Attributes
    ----------
    phase_order, map_order : int
        ``P`` and ``J``.
    method : {"cross_validation", "given", "default"}
        Chosen by cross-validation, given by the user, or the paper's ``(1, 0)`` on a
        sweep of fewer than ``MIN_CV_WINDOWS`` FSR windows (``reason`` says so).
    reason : str
        How the orders were chosen, in words.
    candidates : tuple of dict
        Every candidate scored: ``phase_order``, ``map_order``, ``parameters``,
        ``cv_rms_hz`` (held-out RMS frequency error) and ``chosen``.
    held_out_windows : int
        FSR windows held out in turn.
    sweep_tests : tuple of dict
        The F tests of :func:`raise_orders` on every reading: ``phase_order``,
        ``map_order`` (the larger model), ``p_value`` and ``taken``.
    """

    phase_order: int
    map_order: int
    method: str
    reason: str
    candidates: tuple[dict, ...]
    held_out_windows: int
    sweep_tests: tuple[dict, ...] = ()

    def record(self) -> dict:
        """JSON-ready entries of ``diagnostics_["wideband"]["orders"]``."""
        return {
            "phase_order": self.phase_order,
            "map_order": self.map_order,
            "method": self.method,
            "reason": self.reason,
            "held_out_windows": self.held_out_windows,
            "candidates": [dict(candidate) for candidate in self.candidates],
            "sweep_tests": [dict(test) for test in self.sweep_tests],
        }


def highest_map_order(windows: int) -> int:
    """The highest map order a sweep over ``windows`` FSR windows can tell from the phase
    (``windows - 2``, at least 1, at most ``MAX_MAP_ORDER``)."""
    return int(min(MAX_MAP_ORDER, max(windows - 2, 1)))


def _folds(windows: np.ndarray) -> np.ndarray:
    """Fold of each reading: -1 for the two outermost windows (always trained on), else
    the rank of its window among the inner ones modulo ``CV_FOLDS``."""
    present = np.unique(windows)
    inner = present[1:-1]
    rank = np.searchsorted(inner, windows)
    folds = rank % CV_FOLDS
    folds[(windows == present[0]) | (windows == present[-1])] = -1
    return folds


def select_orders(
    powers,
    frequency_hz,
    center_hz: float,
    half_span_hz: float,
    coefficients_rad,
    fsr_hz: float,
    retrieve: Callable[[np.ndarray, np.ndarray], np.ndarray],
    *,
    scale=None,
    affine: bool = False,
    phase_order: int | None = None,
    map_order: int | None = None,
) -> OrderSelection:
    """Choose the orders ``(P, J)`` left None by cross-validation (module docstring).

    Parameters
    ----------
    powers : ndarray, shape (N, n)
        Readings (W), dark-subtracted.
    frequency_hz : ndarray, shape (N,)
        Known frequencies (Hz).
    center_hz, half_span_hz : float
        ``f0`` and ``h`` (Hz) of the band.
    coefficients_rad : array_like
        Phase coefficients in ``y`` (rad) of a fit over the band, to start from.
    fsr_hz : float
        The FSR (Hz) that cuts the sweep into windows.
    retrieve : callable
        ``retrieve(readings, maps) -> phase`` (the pseudo-inverse's).
    scale, affine
        As for :func:`~wavemeter.calibration.models.wideband_fit.fit_band_region`.
    phase_order, map_order : int or None
        Given orders (kept); None to choose.

    Returns
    -------
    OrderSelection
    """
    rows = evenly(np.arange(powers.shape[0]), CV_READINGS)
    frequency = frequency_hz[rows]
    readings = powers[rows]
    weights = None if scale is None else scale[rows]
    windows = fsr_windows(frequency, float(frequency_hz.min()), fsr_hz)
    present = np.unique(windows).size
    ports = powers.shape[1]
    if phase_order is not None and map_order is not None:
        return OrderSelection(phase_order, map_order, "given", "both orders given", (), 0)
    if present < MIN_CV_WINDOWS:
        return OrderSelection(
            phase_order or 1,
            map_order or 0,
            "default",
            f"the sweep has {present} FSR windows, fewer than the {MIN_CV_WINDOWS} "
            "cross-validation needs: the paper's linear phase and constant map",
            (),
            0,
        )
    folds = _folds(windows)
    held = folds >= 0
    training_windows = present - int(
        max(np.unique(windows[folds == k]).size for k in range(CV_FOLDS))
    )
    highest_map = min(highest_map_order(training_windows), training_windows // 2 - 1)
    highest_phase = min(MAX_PHASE_ORDER, max(training_windows // 2, 1))
    y = (frequency - center_hz) / half_span_hz

    def held_out_errors(orders: tuple[int, int]) -> np.ndarray:
        order_p, order_j = orders
        fit = fit_band_region(
            readings,
            frequency,
            center_hz,
            half_span_hz,
            padded(coefficients_rad, order_p),
            map_order=order_j,
            scale=weights,
            affine=affine,
        )
        phase = band_phase_rad(y, fit.coefficients_rad)
        objects = band_objects(y, phase, weights, order_j, affine)
        errors = np.empty(np.count_nonzero(held))
        positions = np.flatnonzero(held)
        for fold in range(CV_FOLDS):
            train, test = folds != fold, folds == fold
            matrix = least_squares_map(objects[train], readings[train])
            coefficients, offsets = map_coefficients(matrix, order_j)
            model = BandModel(center_hz, half_span_hz, fit.coefficients_rad, coefficients)
            tested = readings[test] - (0.0 if offsets is None else offsets)
            estimate = band_frequency_hz(model, tested, frequency[test], retrieve)[0]
            errors[np.searchsorted(positions, np.flatnonzero(test))] = estimate - frequency[test]
        return errors

    scored: dict[tuple[int, int], np.ndarray] = {}

    def score(orders):
        if orders not in scored:
            scored[orders] = held_out_errors(orders) ** 2
        return scored[orders]

    def allowed(orders):
        order_p, order_j = orders
        return (
            (phase_order is None or order_p == phase_order)
            and (map_order is None or order_j == map_order)
            and 1 <= order_p <= highest_phase
            and 0 <= order_j <= highest_map
        )

    current = (phase_order or 1, map_order or 0)
    rounding_hz2 = (ROUNDING_RESOLUTION * abs(center_hz)) ** 2
    while True:
        best = None
        for step in (1, 2):
            moves = [(current[0] + step, current[1]), (current[0], current[1] + step)]
            for move in filter(allowed, moves):
                lowered = score(current) - score(move)
                spread = lowered.std(ddof=1) / np.sqrt(lowered.size)
                enough = lowered.mean() > max(CV_Z * spread, rounding_hz2)
                if enough and (best is None or lowered.mean() > best[0]):
                    best = (float(lowered.mean()), move)
            if best is not None:
                break
        if best is None:
            break
        current = best[1]
    score(current)
    candidates = tuple(
        {
            "phase_order": order_p,
            "map_order": order_j,
            "parameters": parameter_count(ports, order_p, order_j, affine),
            "cv_rms_hz": float(np.sqrt(errors.mean())),
            "chosen": (order_p, order_j) == current,
        }
        for (order_p, order_j), errors in sorted(scored.items())
    )
    held_windows = int(np.unique(windows[held]).size)
    return OrderSelection(
        current[0],
        current[1],
        "cross_validation",
        f"cross-validation on {held_windows} held-out FSR windows in {CV_FOLDS} folds: "
        f"the smallest model whose held-out error no higher order lowers by {CV_Z:g} "
        "standard errors",
        candidates,
        held_windows,
    )


def raise_orders(
    selection: OrderSelection,
    powers,
    frequency_hz,
    center_hz: float,
    half_span_hz: float,
    coefficients_rad,
    fsr_hz: float,
    *,
    scale=None,
    affine: bool = False,
    phase_fixed: bool = False,
    map_fixed: bool = False,
) -> tuple[OrderSelection, BandFit]:
    """Raise the orders while the whole sweep rejects the smaller model (module docstring).

    Parameters
    ----------
    selection : OrderSelection
        The orders chosen so far.
    powers, frequency_hz, center_hz, half_span_hz, scale, affine
        As for :func:`select_orders`, with every reading.
    coefficients_rad : array_like
        Phase coefficients (rad, in ``y``) to start the fits from.
    fsr_hz : float
        The FSR (Hz) that cuts the sweep into windows.
    phase_fixed, map_fixed : bool
        The phase order or the map order was given: keep it.

    Returns
    -------
    selection : OrderSelection
        With the raised orders, the tests in ``sweep_tests`` and the reason extended.
    fit : BandFit
        The fit at those orders on every reading.
    """
    windows = window_count(frequency_hz, fsr_hz)
    highest_map = highest_map_order(windows)
    ports = powers.shape[1]
    y = (frequency_hz - center_hz) / half_span_hz
    # on one or two FSR windows a map's slope that rotates the fringe is the phase's slope:
    # it is held out (the rotation of the constant map at the start's phase)
    gauge = _rotation(powers, y, coefficients_rad, scale, affine) if windows <= 2 else None

    def fitted(orders, start):
        return fit_band_region(
            powers,
            frequency_hz,
            center_hz,
            half_span_hz,
            padded(start, orders[0]),
            map_order=orders[1],
            scale=scale,
            affine=affine,
            gauge=gauge if orders[1] >= 1 else None,
        )

    current = (selection.phase_order, selection.map_order)
    fit, refit = fitted(current, coefficients_rad), False
    rounding_w2 = max(
        (ROUNDING_RESOLUTION * float(np.abs(powers).max())) ** 2, np.finfo(float).tiny
    )
    tests = []
    while True:
        noise = np.mean(np.square(fit.residual_w), axis=0)
        if np.all(noise <= rounding_w2):
            break  # a residual at float64 rounding: nothing left for a larger model
        noise = np.maximum(noise, np.finfo(float).tiny)
        tried = []
        if not phase_fixed and current[0] < MAX_PHASE_ORDER:
            move = (current[0] + 1, current[1])
            lowered = _phase_order_reduction(fit, y, scale, current[1], affine, noise)
            tried.append((move, lowered, None))
        if not map_fixed and current[1] < highest_map:
            move = (current[0], current[1] + 1)
            larger = _map_order_fit(fit, powers, y, scale, move[1], affine)
            lowered = float(
                np.sum((np.square(fit.residual_w) - np.square(larger.residual_w)) / noise)
            )
            tried.append((move, lowered, larger))
        records = []
        for move, lowered, larger in tried:
            record = {
                "phase_order": move[0],
                "map_order": move[1],
                "p_value": _nested_p_value(fit, lowered, noise, ports, current, move, affine),
                "taken": False,
            }
            records.append((record, move, larger))
        tests += [record for record, _, _ in records]
        significant = [entry for entry in records if entry[0]["p_value"] < TEST_P_VALUE]
        if not significant:
            break
        record, current, larger = min(significant, key=lambda entry: entry[0]["p_value"])
        record["taken"] = True
        # a higher map order is fitted at the phase as it is: refit the phase at the end
        fit, refit = (
            (fitted(current, fit.coefficients_rad), False)
            if larger is None
            else (
                larger,
                True,
            )
        )
    if refit:
        fit = fitted(current, fit.coefficients_rad)
    if current == (selection.phase_order, selection.map_order):
        return dataclasses.replace(selection, sweep_tests=tuple(tests)), fit
    reason = (
        f"{selection.reason}; raised to phase order {current[0]}, map order {current[1]}: "
        f"every reading rejects the smaller model (F test, p < {TEST_P_VALUE:g})"
    )
    raised = dataclasses.replace(
        selection,
        phase_order=current[0],
        map_order=current[1],
        reason=reason,
        sweep_tests=tuple(tests),
    )
    return raised, fit


def _nested_p_value(fit: BandFit, lowered, noise, ports, small, large, affine) -> float:
    """p-value of the F test of ``fit`` against a larger model nesting it that lowers the
    residual energy (whitened by each port's ``noise`` variance) by ``lowered``."""
    energy = float(np.sum(np.square(fit.residual_w) / noise)) - lowered
    added = parameter_count(ports, *large, affine) - parameter_count(ports, *small, affine)
    dof = fit.residual_w.size - parameter_count(ports, *large, affine)
    statistic = max(lowered, 0.0) / added / (max(energy, np.finfo(float).tiny) / dof)
    return float(stats.f.sf(statistic, added, dof))


def _rotation(powers, y, coefficients_rad, scale, affine: bool) -> np.ndarray:
    """``A_0 G`` (n, 3): the rotation about the cone axis of the constant map fitted at the
    phase coefficients (rad, in ``y``)."""
    objects = band_objects(y, band_phase_rad(y, coefficients_rad), scale, 0, affine)
    constant = least_squares_map(objects, powers)[:3].T
    return np.column_stack([constant[:, 1], -constant[:, 0], np.zeros(constant.shape[0])])


def _map_order_fit(fit: BandFit, powers, y, scale, map_order: int, affine: bool) -> BandFit:
    """The map of order ``map_order`` fitted at the phase of ``fit`` (linear least squares:
    the larger model's fit with the phase held, so its lowering is not overstated)."""
    objects = band_objects(y, fit.phase_rad, scale, map_order, affine)
    matrix = least_squares_map(objects, powers)
    residual = powers - objects @ matrix
    return dataclasses.replace(
        fit,
        matrix=matrix,
        cost=float(np.einsum("ij,ij->", residual, residual) / powers.shape[0]),
        residual_w=residual,
    )


def _phase_order_reduction(fit: BandFit, y, scale, map_order, affine, noise) -> float:
    """The whitened residual energy one more phase order removes, to first order (the score
    test): the residual along the new order's direction once the map and the present phase
    orders are projected out of it."""
    order = fit.coefficients_rad.size
    objects = band_objects(y, fit.phase_rad, scale, map_order, affine)
    factor = normal_factor(objects)
    derivatives = band_object_derivatives(y, fit.phase_rad, scale, map_order, affine, order + 1)
    scale_w = 1.0 / np.sqrt(noise)
    columns = []
    for derivative in derivatives:
        image = (derivative @ fit.matrix) * scale_w
        image = image - objects @ linalg.cho_solve(factor, objects.T @ image)
        columns.append(image.ravel())
    present, new = np.column_stack(columns[:-1]), columns[-1]
    new = new - present @ np.linalg.lstsq(present, new, rcond=None)[0]
    along = float(new @ (fit.residual_w * scale_w).ravel())
    return along**2 / max(float(new @ new), np.finfo(float).tiny)
