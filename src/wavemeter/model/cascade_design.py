"""Designing a cascade: the fewest stages that read a band absolutely at a wrong-order rate.

A cascade (:class:`~wavemeter.simulation.cascade.CascadeInterferometer`) splits one source
among ``K`` stages of decreasing FSR ``F_0 > F_1 > ... > F_{K-1}``; the coarsest stage's
phase is unique over the band, and each stage picks the fringe order of the next
(:mod:`wavemeter.model.orders`). :func:`design_cascade` chooses ``K`` (1 to
:data:`MAX_STAGES`) and the FSRs: the finest is given, the others geometric between it and
``F_0``, and ``F_0`` minimises the total wrong-order rate (the coarsest stage's wrap at the
band's edges and every hand-over's error), for ideal stages of equal power share made
``noise_factor`` times noisier and with FSRs off by up to ``fsr_tolerance``.

Theory (the derivation, steps 1-8): the docs' cascade page (``docs/theory/cascade.rst``,
"Designing a cascade").
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ..exceptions import InputError, shown
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
            f"(Hz), got {shown(band_hz)}",
            parameter="band_hz",
        ) from None
    if not (math.isfinite(low) and math.isfinite(high) and high > low):
        raise InputError(
            f"band_hz must be finite with low < high (Hz), got ({shown(low)}, {shown(high)})",
            parameter="band_hz",
        )
    return (low, high), high - low


def _factor(noise_factor) -> float:
    value = _positive("noise_factor", noise_factor)
    if value < 1.0:
        raise InputError(
            "noise_factor must be >= 1 (no stage beats the ideal bound), "
            f"got {shown(noise_factor)}",
            parameter="noise_factor",
        )
    return value


def _tolerance(fsr_tolerance) -> float:
    if fsr_tolerance == 0:
        return 0.0
    return _positive("fsr_tolerance", fsr_tolerance, upper=1.0)


def _ports(ports) -> int:
    if isinstance(ports, bool) or not isinstance(ports, (int, np.integer)) or ports < 3:
        raise InputError(f"ports must be an integer >= 3, got {shown(ports)}", parameter="ports")
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
            f"{MAX_STAGES}, got {shown(stages)}",
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

    Examples
    --------
    >>> import wavemeter as wm
    >>> design = wm.design_cascade((191e12, 196e12), 50e9, wrong_order_rate=1e-9)
    >>> print(len(design.fsrs_hz), [round(fsr / 1e9) for fsr in design.fsrs_hz])
    3 [5999, 548, 50]
    >>> two = wm.design_cascade((191e12, 196e12), 50e9, stages=2)  # too few stages for the band
    >>> print([round(fsr / 1e9) for fsr in two.fsrs_hz], two.wrong_order_rate > 1e-9)
    [5589, 50] True
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
