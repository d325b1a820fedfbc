"""The wrong-order rates of a cascade of stages, and the search for its coarsest FSR.

For fixed inputs (:class:`DesignSetting`: the band, the finest FSR, ports, power, noise, the
noise factor and FSR tolerance), the stages' FSRs are geometric from a coarsest ``F_0`` to
the finest; each hand-over's margin and rate and the coarsest stage's band-averaged wrap
rate follow (items 3, 4 and 8 of :mod:`wavemeter.model.cascade_design`, computed as
logarithms so that neither underflows), and ``F_0`` is chosen for ``K`` stages by
minimising the log of their sum over a log grid refined by a bounded scalar minimisation
(item 6).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, special

from .cascade_result import CascadeDesign
from .limits import crlb_ideal_frequency_std
from .orders import any_error_probability, handover_error_rate

__all__ = ["DesignSetting"]

#: the search for ``F_0``: the smallest and largest relative excess ``F_0 / max(B, F_{K-1}) - 1``
_EXCESS_RANGE = (1e-9, 1e7)
#: points of the log grid over the excess before the bounded refinement
_GRID_POINTS = 97
#: above this margin ``1 - z R(z)`` (``R`` the Mills ratio) is taken from its series
_SERIES_MARGIN = 100.0
#: below this spread ``z' - z`` (relative to ``max(z, 1)``) the band average of ``Q`` is
#: ``Q`` at the middle (the band is narrow against ``s_0``)
_NARROW_SPREAD = 1e-6


def _log_handover_rate(margin):
    """``log`` of :func:`~wavemeter.model.orders.handover_error_rate` at margin ``z``
    (``log 2 Q(z)``), exact also where the rate underflows."""
    return math.log(2.0) + special.log_ndtr(-np.asarray(margin, dtype=float))


def _log_tail_integral(margin: float) -> float:
    """``log g(z)``, ``g(z) = phi(z) - z Q(z) = integral_z^inf Q(u) du``, for ``z >= 0``.

    ``g = phi(z) (1 - z R(z))`` with the Mills ratio ``R = Q / phi``; above
    ``_SERIES_MARGIN`` the bracket comes from its series ``z^-2 (1 - 3 z^-2 + 15 z^-4 -
    105 z^-6)``, next term ``945 z^-8`` (the direct form loses ``z^2`` eps to cancellation).
    """
    log_pdf = -0.5 * margin**2 - 0.5 * math.log(2.0 * math.pi)
    if margin > _SERIES_MARGIN:
        inverse_square = margin**-2
        series = 1.0 - 3.0 * inverse_square + 15.0 * inverse_square**2 - 105.0 * inverse_square**3
        return log_pdf + math.log(inverse_square * series)
    mills = math.sqrt(math.pi / 2.0) * special.erfcx(margin / math.sqrt(2.0))
    return log_pdf + math.log(1.0 - margin * mills)


def _log_edge_rate(coarsest_fsr_hz: float, coarsest_std_hz: float, band_width_hz: float):
    """``log`` of the band-averaged wrap rate of the coarsest stage, both ends (item 4 of
    :mod:`wavemeter.model.cascade_design`).

    Returns
    -------
    float
        ``log(2 (s_0 / B) (g(z) - g(z')))``.
    """
    near = (coarsest_fsr_hz - band_width_hz) / (2.0 * coarsest_std_hz)
    far = (coarsest_fsr_hz + band_width_hz) / (2.0 * coarsest_std_hz)
    if far - near < _NARROW_SPREAD * max(near, 1.0):
        return math.log(2.0) + float(special.log_ndtr(-(near + far) / 2.0))
    log_near = _log_tail_integral(near)
    log_difference = log_near + math.log1p(-math.exp(_log_tail_integral(far) - log_near))
    return math.log(2.0 * coarsest_std_hz / band_width_hz) + log_difference


@dataclass(frozen=True)
class DesignSetting:
    """What is fixed while ``F_0`` and ``K`` are searched."""

    band_hz: tuple[float, float] | None
    band_width_hz: float
    finest_fsr_hz: float
    ports: int
    power_w: float
    noise_w: float
    requested_rate: float
    noise_factor: float
    fsr_tolerance: float

    def fsrs_hz(self, coarsest_fsr_hz: float, stages: int) -> tuple[float, ...]:
        """Geometric FSRs from ``coarsest_fsr_hz`` to the finest, which is kept exact."""
        if stages == 1:
            return (self.finest_fsr_hz,)
        steps = np.arange(stages - 1) / (stages - 1)
        ratio = self.finest_fsr_hz / coarsest_fsr_hz
        return (*(float(coarsest_fsr_hz * ratio**step) for step in steps), self.finest_fsr_hz)

    def stage_std_hz(self, fsrs_hz) -> tuple[float, ...]:
        stage_power_w = self.power_w / len(fsrs_hz)
        return tuple(
            self.noise_factor
            * float(crlb_ideal_frequency_std(self.ports, stage_power_w, self.noise_w, fsr))
            for fsr in fsrs_hz
        )

    def margins(self, fsrs_hz, stds_hz) -> np.ndarray:
        """Each hand-over's margin (std) with the coarser FSR ``fsr_tolerance`` above its
        design and the finer one below it (item 8 of :mod:`wavemeter.model.cascade_design`)."""
        wider, narrower = 1.0 + self.fsr_tolerance, 1.0 - self.fsr_tolerance
        stds = np.asarray(stds_hz)
        half = np.asarray(fsrs_hz[1:]) * narrower / 2.0
        return half / np.hypot(stds[:-1] * wider, stds[1:] * narrower)

    def log_edge_rate(self, fsrs_hz, stds_hz) -> float:
        """``log`` of the wrap rate with the coarsest FSR ``fsr_tolerance`` below its
        design (its unique range then narrowest)."""
        narrower = 1.0 - self.fsr_tolerance
        return _log_edge_rate(fsrs_hz[0] * narrower, stds_hz[0] * narrower, self.band_width_hz)

    def edge_margin(self, fsrs_hz, stds_hz) -> float:
        """``(F_0 - B) / (2 s_0)`` with the coarsest FSR ``fsr_tolerance`` below its design."""
        narrower = 1.0 - self.fsr_tolerance
        return (fsrs_hz[0] * narrower - self.band_width_hz) / (2.0 * stds_hz[0] * narrower)

    def log_rate(self, coarsest_fsr_hz: float, stages: int) -> float:
        """``log`` of the sum of the wrap and hand-over rates (the search's objective)."""
        fsrs = self.fsrs_hz(coarsest_fsr_hz, stages)
        stds = np.array(self.stage_std_hz(fsrs))
        terms = [self.log_edge_rate(fsrs, stds)]
        terms += list(_log_handover_rate(self.margins(fsrs, stds)))
        return float(special.logsumexp(terms))

    def design(self, coarsest_fsr_hz: float, stages: int) -> CascadeDesign:
        fsrs = self.fsrs_hz(coarsest_fsr_hz, stages)
        stds = self.stage_std_hz(fsrs)
        margins = self.margins(fsrs, stds)
        # the rate at margin z: erfc(z / sqrt 2), as for a half FSR of z standard deviations
        handover_rates = handover_error_rate(2.0 * margins, 1.0)
        edge_rate = math.exp(self.log_edge_rate(fsrs, stds))
        total = any_error_probability(np.array([edge_rate, *handover_rates]))
        return CascadeDesign(
            fsrs_hz=fsrs,
            wrong_order_rate=float(total),
            handover_margins=tuple(float(margin) for margin in margins),
            handover_rates=tuple(float(rate) for rate in handover_rates),
            ratios=tuple(fsrs[k] / fsrs[k + 1] for k in range(stages - 1)),
            stage_std_hz=stds,
            edge_margin=self.edge_margin(fsrs, stds),
            edge_rate=edge_rate,
            band_hz=self.band_hz,
            band_width_hz=self.band_width_hz,
            ports=self.ports,
            power_w=self.power_w,
            noise_w=self.noise_w,
            requested_rate=self.requested_rate,
            noise_factor=self.noise_factor,
            fsr_tolerance=self.fsr_tolerance,
        )

    def best(self, stages: int) -> CascadeDesign | None:
        """The rate-minimising design of ``stages`` stages; None when ``K = 1`` and the
        finest FSR does not exceed the band."""
        narrowest = self.band_width_hz / (1.0 - self.fsr_tolerance)
        if stages == 1:
            if self.finest_fsr_hz <= narrowest:
                return None
            return self.design(self.finest_fsr_hz, 1)
        floor_hz = max(narrowest, self.finest_fsr_hz)

        def objective(log_excess: float) -> float:
            return self.log_rate(floor_hz * (1.0 + math.exp(log_excess)), stages)

        grid = np.linspace(*np.log(_EXCESS_RANGE), _GRID_POINTS)
        best = int(np.argmin([objective(point) for point in grid]))
        bracket = (grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)])
        found = optimize.minimize_scalar(
            objective, bounds=bracket, method="bounded", options={"xatol": 1e-6}
        )
        log_excess = found.x if found.fun <= objective(grid[best]) else grid[best]
        return self.design(floor_hz * (1.0 + math.exp(log_excess)), stages)
