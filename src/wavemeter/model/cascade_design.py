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

import numpy as np

from ..exceptions import InputError
from ..validation import check_positive
from .cascade_result import CascadeDesign
from .cascade_search import DesignSetting

__all__ = [
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
    setting = DesignSetting(
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
