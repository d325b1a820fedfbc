"""One-dimensional search for the delay ``tau`` (equivalently the FSR) that minimises a cost.

The cost ``J(tau)`` of a sweep spanning ``K`` FSRs has local minima about ``1/K`` apart in
relative delay, so a plain golden-section search over a wide bracket can stop on a wrong
one. The search first scans the bracket on a grid finer than that spacing, then refines the
best grid point with scipy's golden-section search (the paper's choice) or bounded Brent.

The main minimum of ``J`` is about ``2/K`` wide (between its first side minima) and
removes nearly all the fringe power, while a side minimum removes only a few per cent of
it. A scan step of ``1/(8 K)`` puts several grid points inside the main minimum, so the
best grid point lies in it whenever the true delay is inside the bracket. When the true
delay lies outside, the best grid point is on the bracket edge, or (for ``K`` of a few or
more) on a side minimum inside; given the cost of a model that explains no fringe at all,
:func:`check_fringes_explained` tells the two apart.

The scan has ``8 K (u_hi - u_lo)`` points (``u`` the delay relative to design); brackets
that need more than ``MAX_GRID_POINTS`` are refused before anything is evaluated, so the
memory and the number of cost evaluations are bounded whatever the inputs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..exceptions import EdgeMinimumError, InputError
from ..validation import check_choice, check_positive

__all__ = [
    "DEFAULT_FSR_TOLERANCE",
    "DelaySearchResult",
    "EdgeMinimumError",
    "MAX_GRID_POINTS",
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
#: largest scan: 8 points per side-minimum spacing, e.g. +-20 % on a sweep of 1200 FSRs
MAX_GRID_POINTS = 4096
#: a fit at the true delay removes all but the noise; a side minimum removes a few per cent
MIN_EXPLAINED_FRACTION = 0.5

_PREFIXES = ((1e12, "THz"), (1e9, "GHz"), (1e6, "MHz"), (1e3, "kHz"))


def frequency_text(value_hz: float, digits: int = 6) -> str:
    """A frequency with the largest SI prefix that keeps it >= 1, ``digits`` significant."""
    for factor, unit in _PREFIXES:
        if abs(value_hz) >= factor:
            return f"{value_hz / factor:.{digits}g} {unit}"
    return f"{value_hz:.{digits}g} Hz"


def _bracket_text(fsr_hz: float, fsr_tolerance: float) -> str:
    return f"fsr_hz={fsr_hz / 1e9:.6g} GHz, fsr_tolerance={fsr_tolerance:g}"


def _largest_tolerance(width: float) -> float:
    """The tolerance ``t`` whose bracket ``1/(1-t) - 1/(1+t) = 2t / (1 - t^2)`` is ``width``."""
    return (np.sqrt(1.0 + width**2) - 1.0) / width


def check_fringes_explained(
    cost: float, unfitted_cost: float, *, fsr_hz: float, fsr_tolerance: float
) -> float:
    """Fraction of the fringe power a fit removes; raise when it is below one half.

    Parameters
    ----------
    cost : float
        Cost ``J`` at the best delay (W^2 for the learned map).
    unfitted_cost : float
        Cost of a model that explains no fringe (the readings about their mean, or about
        the power-monitor scaling), same unit as ``cost``.
    fsr_hz, fsr_tolerance : float
        The bracket searched, for the message.

    Returns
    -------
    float
        ``1 - cost / unfitted_cost``: about 1 at the true delay with fringes well above the
        noise, a few per cent on a side minimum.

    Raises
    ------
    EdgeMinimumError
        When the fraction is below ``MIN_EXPLAINED_FRACTION`` (0.5): the best delay in the
        bracket is a side minimum, so the true FSR lies outside the bracket (or the
        readings carry no fringes above the noise).
    """
    if not unfitted_cost > 0:
        raise InputError(
            f"unfitted_cost must be > 0 (the readings vary about their mean), got {unfitted_cost!r}"
        )
    explained = 1.0 - cost / unfitted_cost
    if explained < MIN_EXPLAINED_FRACTION:
        raise EdgeMinimumError(
            f"the best delay fit in the FSR bracket ({_bracket_text(fsr_hz, fsr_tolerance)}) "
            f"explains only {100 * explained:.3g} % of the fringe power, a side minimum: the "
            "true FSR is outside the bracket (or the readings carry no fringes above the noise); "
            "widen fsr_tolerance or correct fsr_hz"
        )
    return explained


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
    unfitted_cost: float | None = None,
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
    unfitted_cost : float, optional
        Cost of a model that explains no fringe (see :func:`check_fringes_explained`).
        When given, a best delay that is only a side minimum raises, which catches a true
        FSR outside the bracket on sweeps of several FSRs.

    Returns
    -------
    DelaySearchResult

    Raises
    ------
    EdgeMinimumError
        When the smallest cost lies on an edge of the bracket, or (with ``unfitted_cost``)
        when the best delay inside it is a side minimum.
    InputError
        When the bracket needs more than ``MAX_GRID_POINTS`` scan points
        (``parameter="fsr_tolerance"``); nothing is evaluated then.
    """
    fsr_hz = check_positive("fsr_hz", fsr_hz)
    fsr_tolerance = check_positive("fsr_tolerance", fsr_tolerance, upper=1.0)
    check_choice("search", method, SEARCH_METHODS)
    design_delay = 1.0 / fsr_hz
    # Search the dimensionless delay u = tau / tau_design; FSR = fsr_hz / u.
    u_lo, u_hi = 1.0 / (1.0 + fsr_tolerance), 1.0 / (1.0 - fsr_tolerance)
    span_hz = check_positive("span_hz", span_hz)
    step = fsr_hz / (GRID_POINTS_PER_MINIMUM * span_hz)
    needed = (u_hi - u_lo) / step + 1.0
    if needed > MAX_GRID_POINTS:
        largest = _largest_tolerance((MAX_GRID_POINTS - 1) * step)
        raise InputError(
            f"the FSR bracket ({_bracket_text(fsr_hz, fsr_tolerance)}) on a sweep over "
            f"{span_hz / fsr_hz:.6g} FSRs needs {needed:.3g} trial delays to keep "
            f"{GRID_POINTS_PER_MINIMUM} per side-minimum spacing, more than the "
            f"{MAX_GRID_POINTS} allowed: narrow fsr_tolerance to at most {largest:.3g} "
            "(with fsr_hz close to the true FSR), or calibrate on a shorter sweep",
            parameter="fsr_tolerance",
        )
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
            f"{_bracket_text(fsr_hz, fsr_tolerance)}): the true FSR is outside it; widen "
            "fsr_tolerance or correct fsr_hz"
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
    if unfitted_cost is not None:
        check_fringes_explained(
            cost_best, unfitted_cost, fsr_hz=fsr_hz, fsr_tolerance=fsr_tolerance
        )
    return DelaySearchResult(
        delay_s=u_best * design_delay,
        cost=cost_best,
        evaluations=points + int(result.nfev),
        grid_delay_s=grid * design_delay,
        grid_cost=grid_cost,
    )
