"""The delay search on a sweep's binned moments: scan and bracket with ``J``, then the root
of ``J'``.

``J`` from sums cancels to about ``1e-9`` of itself, ample for scanning and bracketing its
minimum but not for locating it to better than about ``1e-8`` relative; its derivative
``J'`` (the map profiled out) has no such cancellation at its root, which
:func:`search_moment_delay` finds to the delay tolerance after the scan of
:func:`~wavemeter.calibration.models.delay_search.search_delay`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import optimize

from .delay_search import DelaySearchResult, search_delay
from .moments import FringeMoments

__all__ = ["search_moment_delay"]


def search_moment_delay(
    moments: FringeMoments,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    method: str = "golden",
    xtol: float = 1e-12,
    affine: bool = False,
) -> DelaySearchResult:
    """:func:`~wavemeter.calibration.models.delay_search.search_delay` on the moments' ``J``, then
    the root of ``J'`` between the best scan point's neighbours, inside the bracket.

    The scan, the edge descent, the refinement, the fringe-power check and the bracket
    decision are :func:`~wavemeter.calibration.models.delay_search.search_delay`'s. Its refined
    delay is precise to about ``1e-8`` only (``J`` cancels); ``J'`` changing sign between
    the scan neighbours of the best point (clipped to the closed bracket) is then solved
    by Brent's method to ``xtol`` (relative). Without a sign change there the refined
    delay stands.

    Parameters
    ----------
    moments : FringeMoments
        The sweep, accumulated to a ``max_delay_s`` of at least
        :func:`largest_search_delay_s`.
    fsr_hz, fsr_tolerance, method, xtol
        As for :func:`~wavemeter.calibration.models.delay_search.search_delay`.
    affine : bool
        Fit per-port offsets too.

    Returns
    -------
    DelaySearchResult
        ``delay_s`` the root, ``cost`` the moments' ``J`` there, ``evaluations`` counting
        the derivative evaluations too; the scan as :func:`search_delay` made it.
    """
    result = search_delay(
        lambda delay_s: moments.cost(delay_s, affine),
        fsr_hz=fsr_hz,
        fsr_tolerance=fsr_tolerance,
        span_hz=moments.span_hz,
        method=method,
        xtol=xtol,
        unfitted_cost=moments.unfitted_cost(affine),
    )
    design_delay = 1.0 / fsr_hz
    best = int(np.argmin(result.grid_cost))
    u_lo = max(result.grid_delay_s[best - 1] / design_delay, 1.0 / (1.0 + fsr_tolerance))
    u_hi = min(result.grid_delay_s[best + 1] / design_delay, 1.0 / (1.0 - fsr_tolerance))

    def slope(u: float) -> float:
        return moments.cost_derivative(u * design_delay, affine)

    if not slope(u_lo) < 0.0 < slope(u_hi):
        return dataclasses.replace(result, evaluations=result.evaluations + 2)
    u_root, info = optimize.brentq(
        slope, u_lo, u_hi, xtol=xtol, rtol=4 * np.finfo(float).eps, full_output=True
    )
    delay = u_root * design_delay
    return dataclasses.replace(
        result,
        delay_s=delay,
        cost=moments.cost(delay, affine),
        evaluations=result.evaluations + 3 + info.function_calls,
    )
