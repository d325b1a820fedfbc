"""Designing a cascade: the fewest stages that read a band absolutely at a wrong-order rate.

A cascade (:class:`~wavemeter.simulation.cascade.CascadeInterferometer`) splits one source
among ``K`` stages of decreasing FSR ``F_0 > F_1 > ... > F_{K-1}``; the coarsest stage's
phase is unique over the band, and each stage picks the fringe order of the next (see
:mod:`wavemeter.model.orders`). :func:`design_cascade` chooses ``K`` and the FSRs.

Derivation (ideal stages, equal power split)
--------------------------------------------
1. Stage power: the source power ``P`` is split equally, each stage receives ``P / K``
   (an unequal split is left for later).
2. Stage noise: an ideal ``n``-port stage with detector noise ``sigma`` per port (W) has
   phase std ``sigma_phi = sqrt(2 n) sigma / (P / K)`` (rad), so its frequency std is
   ``s_k = F_k sigma_phi / (2 pi)``
   (:func:`~wavemeter.model.limits.crlb_ideal_frequency_std`). Every ``s_k`` is
   proportional to its FSR: ``s_k = c F_k``, ``c = sqrt(2 n) sigma K / (2 pi P)``.
3. Hand-over ``k -> k+1``: the residual of the two stages' errors has std
   ``s = sqrt(s_k^2 + s_{k+1}^2)``; the order is wrong when it exceeds half the finer FSR,
   ``|e_k - e_{k+1}| > F_{k+1} / 2``. Its margin, in standard deviations, is
   ``z_k = (F_{k+1} / 2) / s = 1 / (2 c sqrt(r_k^2 + 1))`` with the ratio
   ``r_k = F_k / F_{k+1}``, and its rate is ``erfc(z_k / sqrt 2) = 2 Q(z_k)``
   (:func:`~wavemeter.model.orders.handover_error_rate`).
4. Coarsest stage: its unique range is ``F_0`` wide, centred on the band ``[low, high]``
   of width ``B < F_0``. A reading whose truth lies a distance ``d`` inside an end of the
   range wraps past it with probability ``Q(d / s_0)``
   (:func:`~wavemeter.model.orders.edge_error_probability`). The truth is uniform over the
   band, so ``d`` runs from ``a = (F_0 - B) / 2`` to ``a + B`` for each end, and that
   end's wrap rate is ``(1 / B) integral_a^{a+B} Q(d / s_0) dd``. With
   ``integral_z^inf Q(u) du = phi(z) - z Q(z) =: g(z)`` (``phi`` the normal pdf) it is
   ``(s_0 / B) (g(z) - g(z'))``, ``z = (F_0 - B) / (2 s_0)`` (the edge margin) and
   ``z' = (F_0 + B) / (2 s_0)``; the two ends together wrap at twice that.
   ``g(z') << g(z)`` unless ``s_0`` is comparable with ``B``.
5. Total: a reading is wrong when any of the ``K`` events (the wrap and the ``K - 1``
   hand-overs) happens, ``1 - prod (1 - p)``
   (:func:`~wavemeter.model.orders.any_error_probability`).
6. FSRs: the last is ``finest_fsr_hz``; the others are geometric between ``F_0`` and it,
   so every hand-over has the same ratio ``r = (F_0 / F_{K-1})^(1 / (K - 1))`` and, by 3,
   the same margin. ``F_0`` is the one free number: a larger ``F_0`` widens the edge
   margin (4) and narrows every hand-over's (3). It is chosen by minimising the total
   rate; the search works on the logarithm of the sum of the rates (equal to the total
   where it matters, and neither underflowing at large margins nor saturating at small
   ones), over a log grid of ``F_0 / max(B, F_{K-1}) - 1`` refined by a bounded scalar
   minimisation.
7. Stages: the fewest ``K`` (1 to :data:`MAX_STAGES`) whose best design meets the
   requested rate. ``K = 1`` means the finest stage alone covers the band (``F_0 =
   finest_fsr_hz > B``) at that rate.
8. Real stages: a chip's stages are noisier than ideal and its FSRs miss their design.
   Every ``s_k`` is ``noise_factor`` times the ideal one, and the rates are those of the
   worst FSRs within ``fsr_tolerance`` (``t``): in 4 the coarsest FSR is ``F_0 (1 - t)``
   (with its std), and in 3 the coarser stage's FSR and std are ``(1 + t)`` times their
   design and the finer's ``(1 - t)`` times, ``z_k = (1 - t) F_{k+1} / 2 / sqrt(((1 + t)
   s_k)^2 + ((1 - t) s_{k+1})^2)``. ``noise_factor = 1`` and ``t = 0`` give 1-7 as they
   stand.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass

import numpy as np
from scipy import optimize, special

from ..exceptions import InputError
from ..validation import check_positive
from .limits import crlb_ideal_frequency_std
from .orders import any_error_probability, handover_error_rate

__all__ = [
    "CascadeDesign",
    "design_cascade",
    "MAX_STAGES",
    "DEFAULT_NOISE_FACTOR",
    "DEFAULT_FSR_TOLERANCE",
]

#: the most stages :func:`design_cascade` considers
MAX_STAGES = 8
#: the stages' noise over the ideal bound a design allows for (see design_cascade)
DEFAULT_NOISE_FACTOR = 2.0
#: the relative FSR error a design allows for (twice Table 1's 5 % delay spread)
DEFAULT_FSR_TOLERANCE = 0.1

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
    """``log`` of the band-averaged wrap rate of the coarsest stage, both ends (item 4 of the
    module docstring).

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
class CascadeDesign:
    """A cascade of ideal stages chosen by :func:`design_cascade`.

    Attributes
    ----------
    fsrs_hz : tuple of float, shape (K,)
        Stage FSRs (Hz), coarsest first; the last is ``finest_fsr_hz`` exactly.
    wrong_order_rate : float
        Predicted probability per reading that some stage's order is wrong (the coarsest
        stage wraps or a hand-over picks the wrong order).
    handover_margins : tuple of float, shape (K - 1,)
        Margin of each hand-over ``k -> k+1``: half the finer FSR over the residual's
        standard deviation (standard deviations).
    handover_rates : tuple of float, shape (K - 1,)
        Wrong-order rate of each hand-over (per reading).
    ratios : tuple of float, shape (K - 1,)
        ``F_k / F_{k+1}`` of each hand-over (all equal).
    stage_std_hz : tuple of float, shape (K,)
        Frequency standard deviation of each stage at its share of the power (Hz): the
        ideal bound times ``noise_factor``.
    edge_margin : float
        How far the coarsest stage's unique range reaches beyond each end of the band, in
        that stage's standard deviations: ``(F_0 - B) / (2 s_0)``.
    edge_rate : float
        Wrap rate of the coarsest stage, averaged over readings uniform over the band.
    band_hz : (float, float) or None
        The band (Hz, low and high); None when only its width was given.
    band_width_hz : float
        Width ``B`` of the band (Hz).
    ports : int
        Ports per stage.
    power_w : float
        Source power entering the cascade (W); each stage receives ``power_w / K``.
    noise_w : float
        Detector noise standard deviation per port and reading (W).
    requested_rate : float
        The wrong-order rate asked for (per reading).
    noise_factor : float
        The stages' noise over the ideal bound the design allows for.
    fsr_tolerance : float
        The relative error of every FSR the design allows for: margins and rates are
        those of the worst case (item 8 of the module docstring).
    """

    fsrs_hz: tuple[float, ...]
    wrong_order_rate: float
    handover_margins: tuple[float, ...]
    handover_rates: tuple[float, ...]
    ratios: tuple[float, ...]
    stage_std_hz: tuple[float, ...]
    edge_margin: float
    edge_rate: float
    band_hz: tuple[float, float] | None
    band_width_hz: float
    ports: int
    power_w: float
    noise_w: float
    requested_rate: float
    noise_factor: float = 1.0
    fsr_tolerance: float = 0.0

    @property
    def stages(self) -> int:
        """Number of stages ``K``."""
        return len(self.fsrs_hz)

    @property
    def stage_power_w(self) -> float:
        """Power each stage receives (W): ``power_w / K``."""
        return self.power_w / self.stages

    @property
    def meets_rate(self) -> bool:
        """Whether the predicted wrong-order rate is at most the requested one."""
        return self.wrong_order_rate <= self.requested_rate

    def to_dict(self) -> dict:
        """The design as plain JSON-ready values, units in the key names, plus
        ``stages``, ``stage_power_w`` and ``meets_rate``."""
        values = {
            name: list(value) if isinstance(value, tuple) else value
            for name, value in asdict(self).items()
        }
        return {
            **values,
            "stages": self.stages,
            "stage_power_w": self.stage_power_w,
            "meets_rate": self.meets_rate,
        }

    def __str__(self) -> str:
        """An aligned table: one row per stage (FSR, ratio to the next, stage std, margin
        and rate of its hand-over to the next), then the wrap and total rates."""
        header = ("stage", "FSR GHz", "ratio", "std MHz", "margin (std)", "hand-over rate")
        rows = []
        for index, (fsr, std) in enumerate(zip(self.fsrs_hz, self.stage_std_hz, strict=True)):
            handover = index < self.stages - 1
            rows.append(
                (
                    str(index + 1),
                    f"{fsr / 1e9:.6g}",
                    f"{self.ratios[index]:.4g}" if handover else "-",
                    f"{std / 1e6:.5g}",
                    f"{self.handover_margins[index]:.2f}" if handover else "-",
                    _rate_text(self.handover_rates[index]) if handover else "-",
                )
            )
        widths = [max(len(row[column]) for row in (header, *rows)) for column in range(6)]
        lines = [
            "  ".join(cell.rjust(width) for cell, width in zip(row, widths, strict=True))
            for row in (header, *rows)
        ]
        band = (
            f"{self.band_hz[0] / 1e12:.6g}-{self.band_hz[1] / 1e12:.6g} THz, "
            if self.band_hz is not None
            else ""
        )
        lines += [
            f"band: {band}{self.band_width_hz / 1e9:.6g} GHz wide; stage 1's range reaches "
            f"{self.edge_margin:.2f} std beyond each end: wrap rate {_rate_text(self.edge_rate)}",
            f"{self.stages} stage(s) of {self.ports} ports, each {self.stage_power_w:.4g} W "
            f"(source {self.power_w:.4g} W), detector noise {self.noise_w:.4g} W per port; "
            f"stages {self.noise_factor:g}x the ideal noise, FSRs within "
            f"{100 * self.fsr_tolerance:g} % (margins and rates at the worst)",
            f"wrong-order rate per reading: {_rate_text(self.wrong_order_rate)} predicted "
            f"({_rate_text(self.requested_rate)} requested)",
        ]
        return "\n".join(lines)


def _rate_text(rate: float) -> str:
    """A rate with 3 digits; one too small for a double is shown as ``< 1e-300``."""
    return f"{rate:.3g}" if rate > 1e-300 else "< 1e-300"


# ---------------------------------------------------------------------------- checks
def _positive(name: str, value, *, upper: float | None = None) -> float:
    try:
        return check_positive(name, value, upper=upper)
    except InputError as exc:
        raise InputError(str(exc), parameter=name) from None


def _band(band_hz) -> tuple[tuple[float, float] | None, float]:
    """The band (low, high) or None, and its width (Hz)."""
    if isinstance(band_hz, numbers.Real) and not isinstance(band_hz, bool):
        return None, _positive("band_hz", band_hz)
    try:
        low, high = (float(edge) for edge in band_hz)
    except (TypeError, ValueError):
        raise InputError(
            "band_hz must be a (low, high) pair of frequencies in Hz, or the band's width "
            f"(Hz), got {band_hz!r}",
            parameter="band_hz",
        ) from None
    if not (math.isfinite(low) and math.isfinite(high) and high > low):
        raise InputError(
            f"band_hz must be finite with low < high (Hz), got ({low!r}, {high!r})",
            parameter="band_hz",
        )
    return (low, high), high - low


def _factor(noise_factor) -> float:
    value = _positive("noise_factor", noise_factor)
    if value < 1.0:
        raise InputError(
            f"noise_factor must be >= 1 (no stage beats the ideal bound), got {noise_factor!r}",
            parameter="noise_factor",
        )
    return value


def _tolerance(fsr_tolerance) -> float:
    if fsr_tolerance == 0:
        return 0.0
    return _positive("fsr_tolerance", fsr_tolerance, upper=1.0)


def _ports(ports) -> int:
    if isinstance(ports, bool) or not isinstance(ports, (int, np.integer)) or ports < 3:
        raise InputError(f"ports must be an integer >= 3, got {ports!r}", parameter="ports")
    return int(ports)


def _stage_count(stages) -> int | None:
    if stages is None:
        return None
    if (
        isinstance(stages, bool)
        or not isinstance(stages, (int, np.integer))
        or not 1 <= stages <= MAX_STAGES
    ):
        raise InputError(
            f"stages must be None (the fewest that meet the rate) or an integer from 1 to "
            f"{MAX_STAGES}, got {stages!r}",
            parameter="stages",
        )
    return int(stages)


# ---------------------------------------------------------------------------- the model
@dataclass(frozen=True)
class _Setting:
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
        design and the finer one below it (item 8 of the module docstring)."""
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


def design_cascade(
    band_hz,
    finest_fsr_hz: float,
    *,
    ports: int = 3,
    power_w: float = 1e-3,
    noise_w: float = 5e-7,
    wrong_order_rate: float = 1e-9,
    noise_factor: float = DEFAULT_NOISE_FACTOR,
    fsr_tolerance: float = DEFAULT_FSR_TOLERANCE,
    stages: int | None = None,
) -> CascadeDesign:
    """The fewest stages that read ``band_hz`` absolutely at ``wrong_order_rate``.

    The model, its derivation and the search are in the module docstring: stages
    ``noise_factor`` times noisier than ideal, the source power split equally (each stage
    ``power_w / K``), the finest FSR given, the others geometric, the coarsest chosen to
    minimise the predicted wrong-order rate, every FSR allowed ``fsr_tolerance`` of error.

    Parameters
    ----------
    band_hz : (float, float) or float
        The band readings come from (Hz, low and high; readings uniform over it), or its
        width (Hz).
    finest_fsr_hz : float
        FSR of the finest (last) stage (Hz), > 0: it sets the precision.
    ports : int
        Ports per stage, >= 3.
    power_w : float
        Source power entering the cascade (W), > 0; each stage receives ``power_w / K``
        (an unequal split is left for later).
    noise_w : float
        Detector noise standard deviation per port and reading (W), > 0.
    wrong_order_rate : float
        Requested probability per reading that some stage's order is wrong, in (0, 1).
    noise_factor : float
        The stages' frequency noise over the ideal bound, >= 1. The default 2 covers a
        Table 1 stage at its noisiest phase (the pseudo-inverse's spread over 300 draws:
        median 1.1, 95th percentile 1.56) with the coarsest stage's misfit over a band
        narrower than its FSR (its model-free noise about 1.3x); 1: ideal stages.
    fsr_tolerance : float
        Relative error of every FSR the design must survive, in [0, 1): the coarsest FSR
        that much below its design (its unique range narrowest), each hand-over with the
        coarser FSR above and the finer below. The default 0.1 is twice Table 1's 5 % delay
        spread; 0: exact FSRs.
    stages : int, optional
        Force this many stages (1 to :data:`MAX_STAGES`): the returned design is that
        ``K``'s best, whether or not it meets the rate (see ``CascadeDesign.meets_rate``).
        None (default): the fewest stages that meet it.

    Returns
    -------
    CascadeDesign

    Raises
    ------
    InputError
        A value out of range (``parameter`` names it); ``stages=1`` with a finest FSR not
        wider than the band; no cascade of at most :data:`MAX_STAGES` stages meets the
        rate (``parameter="wrong_order_rate"``; the message gives the best rate reached and
        what would help).
    """
    band, width = _band(band_hz)
    setting = _Setting(
        band_hz=band,
        band_width_hz=width,
        finest_fsr_hz=_positive("finest_fsr_hz", finest_fsr_hz),
        ports=_ports(ports),
        power_w=_positive("power_w", power_w),
        noise_w=_positive("noise_w", noise_w),
        requested_rate=_positive("wrong_order_rate", wrong_order_rate, upper=1.0),
        noise_factor=_factor(noise_factor),
        fsr_tolerance=_tolerance(fsr_tolerance),
    )
    forced = _stage_count(stages)
    if forced is not None:
        design = setting.best(forced)
        if design is None:
            raise InputError(
                f"stages=1 needs finest_fsr_hz ({setting.finest_fsr_hz:.6g} Hz) wider than the "
                f"band ({width:.6g} Hz): its range must cover the band; use more stages",
                parameter="stages",
            )
        return design
    best = None
    for count in range(1, MAX_STAGES + 1):
        design = setting.best(count)
        if design is None:
            continue
        if design.meets_rate:
            return design
        if best is None or design.wrong_order_rate < best.wrong_order_rate:
            best = design
    remedies = "raise power_w, lower noise_w or make finest_fsr_hz coarser"
    if setting.ports > 3:
        remedies += " (or use fewer ports per stage: each adds noise at a fixed noise_w)"
    raise InputError(
        f"no cascade of at most {MAX_STAGES} stages reaches wrong_order_rate "
        f"{setting.requested_rate:.3g} at noise_w {setting.noise_w:.4g} W and power_w "
        f"{setting.power_w:.4g} W: the best is {best.wrong_order_rate:.3g} with "
        f"{best.stages} stage(s) (hand-over margins "
        f"{', '.join(f'{margin:.2f}' for margin in best.handover_margins) or 'none'} std, "
        f"edge margin {best.edge_margin:.2f} std); {remedies}, or accept a higher rate",
        parameter="wrong_order_rate",
    )
