"""One-dimensional search for the delay ``tau`` (equivalently the FSR) that minimises a cost.

The cost ``J(tau)`` of a sweep spanning ``K`` FSRs has local minima about ``1/K`` apart in
relative delay, so a plain golden-section search over a wide bracket can stop on a wrong
one. The search first scans the bracket on a grid finer than that spacing, then refines the
best grid point with scipy's golden-section search (the paper's choice) or bounded Brent.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .validation import check_choice, check_positive

__all__ = ["DelaySearchResult", "EdgeMinimumError", "search_delay", "SEARCH_METHODS"]

SEARCH_METHODS = ("golden", "brent")
GRID_POINTS_PER_MINIMUM = 8
MIN_GRID_POINTS = 17


class EdgeMinimumError(ValueError):
    """The cost is smallest on the edge of the FSR bracket: the true FSR lies outside it."""


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
        The scan, for diagnostics and plots.
    """

    delay_s: float
    cost: float
    evaluations: int
    grid_delay_s: np.ndarray
    grid_cost: np.ndarray


def search_delay(
    cost: Callable[[float], float],
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    span_hz: float,
    method: str = "golden",
    xtol: float = 1e-12,
) -> DelaySearchResult:
    """Find the delay minimising ``cost`` for an FSR within ``fsr_hz * (1 +- fsr_tolerance)``.

    Parameters
    ----------
    cost : callable
        ``cost(delay_s) -> float``.
    fsr_hz : float
        Design FSR (Hz), the centre of the bracket.
    fsr_tolerance : float
        Relative half width of the FSR bracket, in (0, 1).
    span_hz : float
        Frequency span of the sweep (Hz); sets the scan step ``1 / (8 span)`` in delay.
    method : {"golden", "brent"}
        Refinement: scipy's golden-section search or bounded Brent.
    xtol : float
        Relative tolerance on the delay for the refinement.

    Returns
    -------
    DelaySearchResult

    Raises
    ------
    EdgeMinimumError
        When the smallest cost lies on an edge of the bracket.
    """
    fsr_hz = check_positive("fsr_hz", fsr_hz)
    fsr_tolerance = check_positive("fsr_tolerance", fsr_tolerance, upper=1.0)
    check_choice("search", method, SEARCH_METHODS)
    design_delay = 1.0 / fsr_hz
    # Search the dimensionless delay u = tau / tau_design; FSR = fsr_hz / u.
    u_lo, u_hi = 1.0 / (1.0 + fsr_tolerance), 1.0 / (1.0 - fsr_tolerance)
    step = fsr_hz / (GRID_POINTS_PER_MINIMUM * span_hz)
    points = max(MIN_GRID_POINTS, int(np.ceil((u_hi - u_lo) / step)) + 1)
    grid = np.linspace(u_lo, u_hi, points)

    def scaled(u: float) -> float:
        return float(cost(u * design_delay))

    grid_cost = np.array([scaled(u) for u in grid])
    best = int(np.argmin(grid_cost))
    if best in (0, points - 1):
        edge_fsr = fsr_hz / grid[best]
        raise EdgeMinimumError(
            f"the delay fit is best at the edge of the FSR bracket ({edge_fsr / 1e9:.6g} GHz for "
            f"fsr_hz={fsr_hz / 1e9:.6g} GHz, fsr_tolerance={fsr_tolerance:g}): the true FSR is "
            "outside it; widen fsr_tolerance or correct fsr_hz"
        )
    lo, mid, hi = grid[best - 1], grid[best], grid[best + 1]
    if method == "golden":
        result = optimize.minimize_scalar(
            scaled, bracket=(lo, mid, hi), method="golden", options={"xtol": xtol}
        )
        u_best = float(result.x)
    else:
        # fminbound adds sqrt(eps) * |x| to its tolerance: search the offset from the grid
        # point, which is small, so that xtol is honoured
        result = optimize.minimize_scalar(
            lambda offset: scaled(mid + offset),
            bounds=(lo - mid, hi - mid),
            method="bounded",
            options={"xatol": xtol * mid},
        )
        u_best = float(mid + result.x)
    cost_best = float(result.fun)
    if grid_cost[best] < cost_best:  # refinement can only improve on the grid point
        u_best, cost_best = float(mid), float(grid_cost[best])
    return DelaySearchResult(
        delay_s=u_best * design_delay,
        cost=cost_best,
        evaluations=points + int(result.nfev),
        grid_delay_s=grid * design_delay,
        grid_cost=grid_cost,
    )
