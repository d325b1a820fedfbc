"""One-dimensional search for the delay ``tau`` (equivalently the FSR) that minimises a cost.

The cost ``J(tau)`` of a sweep spanning ``K`` FSRs has local minima about ``1/K`` apart in
relative delay, so :func:`search_delay` first scans a grid ``GRID_POINTS_PER_MINIMUM``
times finer than that (:func:`bracket_grid`), continues up to ``EDGE_POINTS`` steps
downhill beyond an end of the bracket, then refines the best point with golden-section
search (the paper's choice) or bounded Brent. An optimum outside the bracket raises
:class:`~wavemeter.exceptions.EdgeMinimumError` naming where the cost is lowest;
:func:`check_fringes_explained` tells a fringe outside the bracket from no fringe at all.
Brackets that would need more than ``MAX_GRID_POINTS`` points are refused before anything
is evaluated.

Theory (the grid step, the edges, the causes): the docs' cone-model page
(``docs/theory/cone.rst``, "The delay search").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ...exceptions import EdgeMinimumError, InputError, shown
from ...units import frequency_text
from ...validation import check_choice, check_positive

__all__ = [
    "DEFAULT_FSR_TOLERANCE",
    "bracket_grid",
    "DelaySearchResult",
    "EDGE_POINTS",
    "EdgeMinimumError",
    "MAX_GRID_POINTS",
    "NO_FRINGE_RATIO",
    "check_fringes_explained",
    "frequency_text",
    "search_delay",
    "SEARCH_METHODS",
]

SEARCH_METHODS = ("golden", "brent")
#: relative half width of the FSR bracket of calibrators that have no setting for it
DEFAULT_FSR_TOLERANCE = 0.2
GRID_POINTS_PER_MINIMUM = 8
MIN_GRID_POINTS = 17
#: scan points beyond an end of the bracket, at most: a minimum up to 3 steps (3/8 of the
#: side-minimum spacing) outside the bracket is resolved and refined
EDGE_POINTS = 4
#: largest scan, edge points included: e.g. +-20 % on a sweep of 1200 FSRs
MAX_GRID_POINTS = 4096
#: a fit at the true delay removes all but the noise; a side minimum removes a few per cent
MIN_EXPLAINED_FRACTION = 0.5
#: readings whose variation about the mean is below this multiple of the noise-only cost
#: carry no fringe above the noise: the fringe would hold less power than the noise, and
#: no delay could explain ``MIN_EXPLAINED_FRACTION`` of the variation
NO_FRINGE_RATIO = 1.0 / (1.0 - MIN_EXPLAINED_FRACTION)


def _bracket_text(fsr_hz: float, fsr_tolerance: float) -> str:
    low, high = fsr_hz * (1.0 - fsr_tolerance), fsr_hz * (1.0 + fsr_tolerance)
    return (
        f"fsr_hz={fsr_hz / 1e9:.6g} GHz, fsr_tolerance={fsr_tolerance:g}: "
        f"{frequency_text(low)} to {frequency_text(high)}"
    )


def _largest_tolerance(width: float) -> float:
    """The tolerance ``t`` whose bracket ``1/(1-t) - 1/(1+t) = 2t / (1 - t^2)`` is ``width``.

    Rounded down to 3 significant digits, so that the value a message prints is allowed.
    """
    exact = (np.sqrt(1.0 + width**2) - 1.0) / width
    scale = 10.0 ** (2 - np.floor(np.log10(exact)))
    return float(np.floor(exact * scale) / scale)


def check_fringes_explained(
    cost: float,
    unfitted_cost: float,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    best_fsr_hz: float | None = None,
    noise_cost: float | None = None,
) -> float:
    """Fraction of the fringe power a fit removes; raise, naming the cause, when below half.

    Parameters
    ----------
    cost : float
        Cost ``J`` at the best delay (W^2 for the learned map).
    unfitted_cost : float
        Cost of a model that explains no fringe (the readings about their mean, or about
        the power-monitor scaling), same unit as ``cost``.
    fsr_hz, fsr_tolerance : float
        The bracket searched, for the message.
    best_fsr_hz : float, optional
        FSR (Hz) of the best delay, for the message.
    noise_cost : float, optional
        Cost that noise alone leaves (same unit): that of a model explaining every fringe,
        e.g. ``n sigma^2`` for white detector noise ``sigma`` on each of ``n`` ports, or
        ``J`` at the fringe period the sweep itself shows, in or out of the bracket. Without
        it a low fraction is reported as a side minimum or missing fringes, undecided.

    Returns
    -------
    float
        ``1 - cost / unfitted_cost``: about 1 at the true delay with fringes well above the
        noise, a few per cent on a side minimum.

    Raises
    ------
    EdgeMinimumError
        When the fraction is below ``MIN_EXPLAINED_FRACTION`` (0.5) and the readings carry
        a fringe (``unfitted_cost`` at least ``NO_FRINGE_RATIO`` times ``noise_cost``, or
        ``noise_cost`` not given): the best delay is a side minimum, so the true FSR lies
        outside the bracket.
    InputError
        With ``parameter="powers"`` when the fraction is below 0.5 and ``unfitted_cost`` is
        less than ``NO_FRINGE_RATIO`` times ``noise_cost``: the readings carry no fringe
        above the noise, whatever the FSR. With ``parameter="unfitted_cost"`` or
        ``"noise_cost"`` when that reference is not a number > 0.
    """
    if not unfitted_cost > 0:
        raise InputError(
            "unfitted_cost must be > 0 (the readings vary about their mean), got "
            f"{shown(unfitted_cost)}",
            parameter="unfitted_cost",
        )
    if noise_cost is not None and not (np.isfinite(noise_cost) and noise_cost > 0):
        raise InputError(
            f"noise_cost must be a finite number > 0, got {shown(noise_cost)}",
            parameter="noise_cost",
        )
    explained = 1.0 - cost / unfitted_cost
    if explained >= MIN_EXPLAINED_FRACTION:
        return explained
    where = "" if best_fsr_hz is None else f", at an FSR of {frequency_text(best_fsr_hz)},"
    fit = (
        "the best delay fit in or next to the FSR bracket "
        f"({_bracket_text(fsr_hz, fsr_tolerance)}){where} explains only "
        f"{100 * explained:.3g} %"
    )
    if noise_cost is None:
        raise EdgeMinimumError(
            f"{fit} of the fringe power, a side minimum: the true FSR is outside the bracket, "
            "or the readings carry no fringes above the noise, or the fringes moved during "
            "the sweep (a chip temperature that changed); widen fsr_tolerance or correct "
            "fsr_hz, or log the chip temperature and calibrate with ThermalCalibrator "
            "(--method thermal)"
        )
    ratio = unfitted_cost / noise_cost
    if ratio < NO_FRINGE_RATIO:
        raise InputError(
            "the readings carry no fringe above the noise: their variation about the mean is "
            f"only {ratio:.3g} times what noise alone leaves (a fringe above the noise makes "
            f"it more than {NO_FRINGE_RATIO:g}), and {fit} of it; no FSR would fit them, so "
            "check that the source sweeps and that the detectors see the interferometer",
            parameter="powers",
        )
    raise EdgeMinimumError(
        f"{fit} of the fringe power, a side minimum, while the readings carry fringes (their "
        f"variation about the mean is {ratio:.3g} times what noise alone leaves): the true "
        "FSR is outside the bracket; widen fsr_tolerance or correct fsr_hz"
    )


@dataclass(frozen=True)
class DelaySearchResult:
    """Outcome of :func:`search_delay`.

    Attributes
    ----------
    delay_s : float
        Delay ``tau`` (s) at the minimum.
    cost : float
        Cost at the minimum.
    evaluations : int
        Number of cost evaluations (grid and refinement).
    grid_delay_s, grid_cost : ndarray
        The scan, for diagnostics and plots, ascending: the bracket and the delays
        (up to ``EDGE_POINTS``) evaluated beyond one end of it when its lowest cost was
        on that end.
    """

    delay_s: float
    cost: float
    evaluations: int
    grid_delay_s: np.ndarray
    grid_cost: np.ndarray


def bracket_grid(fsr_hz: float, fsr_tolerance: float, span_hz: float) -> np.ndarray:
    """Relative delays ``u`` scanning the bracket ``[u_lo, u_hi]``, ends included.

    Raises InputError (``parameter="fsr_tolerance"``) when the bracket and the
    ``EDGE_POINTS`` beyond each end of it need more than ``MAX_GRID_POINTS`` points.
    """
    u_lo, u_hi = 1.0 / (1.0 + fsr_tolerance), 1.0 / (1.0 - fsr_tolerance)
    step = fsr_hz / (GRID_POINTS_PER_MINIMUM * span_hz)
    needed = (u_hi - u_lo) / step + 1.0 + 2 * EDGE_POINTS
    if needed > MAX_GRID_POINTS:
        largest = _largest_tolerance((MAX_GRID_POINTS - 1 - 2 * EDGE_POINTS) * step)
        raise InputError(
            f"the FSR bracket ({_bracket_text(fsr_hz, fsr_tolerance)}) on a sweep over "
            f"{span_hz / fsr_hz:.6g} FSRs needs {needed:.3g} trial delays to keep "
            f"{GRID_POINTS_PER_MINIMUM} per side-minimum spacing, more than the "
            f"{MAX_GRID_POINTS} allowed: narrow fsr_tolerance to at most {largest:.3g} "
            "(with fsr_hz close to the true FSR), or calibrate on a shorter sweep",
            parameter="fsr_tolerance",
        )
    points = max(MIN_GRID_POINTS, int(np.ceil((u_hi - u_lo) / step)) + 1)
    return np.linspace(u_lo, u_hi, points)


def _descend_beyond(
    scaled: Callable[[float], float], grid: np.ndarray, grid_cost: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Extend a scan whose lowest cost is on an end, downhill, by up to ``EDGE_POINTS``.

    Steps of the scan's own spacing beyond that end are evaluated one at a time until the
    cost rises (the minimum is then resolved) or ``EDGE_POINTS`` were taken. Below the
    bracket the delay stays above half of its low end, so it remains positive.
    """
    step = grid[1] - grid[0]
    at_low = int(np.argmin(grid_cost)) == 0
    room = min(EDGE_POINTS, int(0.5 * grid[0] / step)) if at_low else EDGE_POINTS
    edge, previous = (grid[0], grid_cost[0]) if at_low else (grid[-1], grid_cost[-1])
    delays, costs = [], []
    for k in range(1, room + 1):
        delays.append(edge - k * step if at_low else edge + k * step)
        costs.append(scaled(delays[-1]))
        if costs[-1] >= previous:
            break
        previous = costs[-1]
    if at_low:
        return np.concatenate([delays[::-1], grid]), np.concatenate([costs[::-1], grid_cost])
    return np.concatenate([grid, delays]), np.concatenate([grid_cost, costs])


def _outside_bracket(
    fsr_hz: float, fsr_tolerance: float, best_fsr_hz: float, *, resolved: bool
) -> EdgeMinimumError:
    """The error for a cost lowest at ``best_fsr_hz`` (Hz), outside the bracket."""
    low, high = fsr_hz * (1.0 - fsr_tolerance), fsr_hz * (1.0 + fsr_tolerance)
    beyond = 100.0 * max(best_fsr_hz / high - 1.0, 1.0 - best_fsr_hz / low, 0.0)
    place = (
        f"at an FSR of {frequency_text(best_fsr_hz)}, {beyond:.3g} % beyond the edge of the "
        f"FSR bracket ({_bracket_text(fsr_hz, fsr_tolerance)})"
    )
    if resolved:
        return EdgeMinimumError(
            f"the delay fit is best {place}: the true FSR is outside the bracket; widen "
            "fsr_tolerance or correct fsr_hz"
        )
    return EdgeMinimumError(
        f"the delay fit is best at the last delay scanned, {place}: the true FSR is "
        "outside the bracket, at or beyond that; widen fsr_tolerance or correct fsr_hz"
    )


def search_delay(
    cost: Callable[[float], float],
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    span_hz: float,
    method: str = "golden",
    xtol: float = 1e-12,
    unfitted_cost: float | None = None,
    noise_cost: float | None = None,
) -> DelaySearchResult:
    """Find the delay minimising ``cost`` for an FSR within ``fsr_hz * (1 +- fsr_tolerance)``.

    Parameters
    ----------
    cost : callable
        ``cost(delay_s) -> float``; called only at delays of the scan (the bracket and
        at most ``EDGE_POINTS`` steps beyond one end) and between them.
    fsr_hz : float
        Design FSR (Hz), the centre of the bracket.
    fsr_tolerance : float
        Relative half width of the FSR bracket, in (0, 1); the bracket is closed.
    span_hz : float
        Frequency span of the sweep (Hz); sets the scan step ``1 / (8 span)`` in delay.
    method : {"golden", "brent"}
        Refinement: scipy's golden-section search or bounded Brent.
    xtol : float
        Relative tolerance on the delay for the refinement.
    unfitted_cost : float, optional
        Cost of a model that explains no fringe (see :func:`check_fringes_explained`).
        When given, a best delay that is only a side minimum raises, which catches a true
        FSR outside the bracket on sweeps of several FSRs.
    noise_cost : float, optional
        Cost that noise alone leaves (see :func:`check_fringes_explained`); with
        ``unfitted_cost``, tells a side minimum of real fringes from readings that carry
        no fringe at all.

    Returns
    -------
    DelaySearchResult

    Raises
    ------
    EdgeMinimumError
        When the refined minimum lies outside the bracket or the cost is lowest at the
        last delay scanned (the message names that FSR), or (with ``unfitted_cost``) when
        the best delay explains less than half of the fringe power of readings that carry
        fringes.
    InputError
        When the bracket needs more than ``MAX_GRID_POINTS`` scan points
        (``parameter="fsr_tolerance"``; nothing is evaluated then), or (with
        ``unfitted_cost`` and ``noise_cost``) when the readings carry no fringe above the
        noise (``parameter="powers"``).
    """
    fsr_hz = check_positive("fsr_hz", fsr_hz)
    fsr_tolerance = check_positive("fsr_tolerance", fsr_tolerance, upper=1.0)
    check_choice("search", method, SEARCH_METHODS)
    span_hz = check_positive("span_hz", span_hz)
    design_delay = 1.0 / fsr_hz
    # Search the dimensionless delay u = tau / tau_design; FSR = fsr_hz / u.
    grid = bracket_grid(fsr_hz, fsr_tolerance, span_hz)
    u_lo, u_hi = grid[0], grid[-1]

    def scaled(u: float) -> float:
        return float(cost(u * design_delay))

    grid_cost = np.array([scaled(u) for u in grid])
    if int(np.argmin(grid_cost)) in (0, grid.size - 1):
        grid, grid_cost = _descend_beyond(scaled, grid, grid_cost)
    best = int(np.argmin(grid_cost))
    u_best, cost_best, refinements = float(grid[best]), float(grid_cost[best]), 0
    resolved = 0 < best < grid.size - 1
    if resolved:
        lo, mid, hi = grid[best - 1], grid[best], grid[best + 1]
        if method == "golden":
            result = optimize.minimize_scalar(
                scaled, bracket=(lo, mid, hi), method="golden", options={"xtol": xtol}
            )
            u_refined = float(result.x)
        else:
            # fminbound adds sqrt(eps) * |x| to its tolerance: search the offset from the
            # grid point, which is small, so that xtol is honoured
            result = optimize.minimize_scalar(
                lambda offset: scaled(mid + offset),
                bounds=(lo - mid, hi - mid),
                method="bounded",
                options={"xatol": xtol * mid},
            )
            u_refined = float(mid + result.x)
        refinements = int(result.nfev)
        if float(result.fun) <= cost_best:  # refinement can only improve on the grid point
            u_best, cost_best = u_refined, float(result.fun)
    if unfitted_cost is not None:
        check_fringes_explained(
            cost_best,
            unfitted_cost,
            fsr_hz=fsr_hz,
            fsr_tolerance=fsr_tolerance,
            best_fsr_hz=fsr_hz / u_best,
            noise_cost=noise_cost,
        )
    if not (resolved and u_lo <= u_best <= u_hi):
        raise _outside_bracket(fsr_hz, fsr_tolerance, fsr_hz / u_best, resolved=resolved)
    return DelaySearchResult(
        delay_s=u_best * design_delay,
        cost=cost_best,
        evaluations=grid.size + refinements,
        grid_delay_s=grid * design_delay,
        grid_cost=grid_cost,
    )
