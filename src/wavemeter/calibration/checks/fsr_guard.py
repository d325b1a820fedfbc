"""Check a design FSR against the sweep before any delay grid is built.

:func:`check_design_fsr` refuses a design FSR the sweep cannot support (``50`` typed for
50 GHz) with an :class:`~wavemeter.exceptions.InputError` (``parameter="fsr_hz"``) that
states the FSR the sweep itself shows. Three checks, in order: sampling (every trial FSR
sees less than half a fringe per reading), span (at least ``MIN_SPAN_FSR`` of the design
FSR), agreement (the sweep's own fringe period from :func:`estimate_fsr` within the
searched bracket widened by ``AGREEMENT_MARGIN``). The estimate scores the strongest
periodogram peaks and short trial delays by the learned-map cost ``J``, on at most
``MAX_ESTIMATE_POINTS`` resampled readings.

Theory (why each check, how the estimate is made): the docs' fit-diagnostics page
(``docs/theory/diagnostics.rst``, "Checking the design FSR against the sweep").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ...exceptions import InputError
from ..models.delay_search import MIN_EXPLAINED_FRACTION, frequency_text
from ..models.linear_map import map_cost, object_vectors, unfitted_cost
from ..models.moments import FringeMoments, binning_pays
from ..models.subsample import median_step_hz

__all__ = [
    "AGREEMENT_MARGIN",
    "FsrEstimate",
    "MAX_ESTIMATE_POINTS",
    "MIN_SPAN_FSR",
    "check_design_fsr",
    "estimate_fsr",
]

#: the sweep must cover at least this fraction of the design FSR
MIN_SPAN_FSR = 0.1
#: a design FSR is refused when the sweep's estimate lies beyond the bracket by this factor
AGREEMENT_MARGIN = 1.25
#: readings the periodogram resamples the sweep onto, at most
MAX_ESTIMATE_POINTS = 1 << 16
#: zero padding of the periodogram: bins 1 / (PADDING span) apart in delay
PADDING = 8
#: strongest periodogram peaks scored by the cost J
PEAKS_SCORED = 4


@dataclass(frozen=True)
class FsrEstimate:
    """The fringe period a sweep shows by itself (:func:`estimate_fsr`).

    Attributes
    ----------
    fsr_hz : float
        Estimated FSR (Hz).
    delay_s : float
        ``1 / fsr_hz`` (s).
    explained : float
        Fraction of the readings' variance about their mean that the learned map at this
        delay explains, in [0.5, 1].
    """

    fsr_hz: float
    delay_s: float
    explained: float


def _periodogram_delays(powers: np.ndarray, frequency_hz: np.ndarray, span_hz: float):
    """Delays (s) of the strongest peaks of the summed port periodogram."""
    order = np.argsort(frequency_hz, kind="stable")
    points = min(max(powers.shape[0], 4), MAX_ESTIMATE_POINTS)
    grid = np.linspace(frequency_hz[order[0]], frequency_hz[order[-1]], points)
    length = 1 << int(np.ceil(np.log2(PADDING * points)))
    spectrum = np.zeros(length // 2 + 1)
    for port in powers.T:  # one port at a time keeps the memory to one padded column
        resampled = np.interp(grid, frequency_hz[order], port[order])
        transform = np.fft.rfft(resampled - resampled.mean(), n=length)
        spectrum += transform.real**2 + transform.imag**2
    bin_delay_s = (points - 1) / (length * span_hz)
    inner = np.arange(1, spectrum.size - 1)
    peaks = inner[
        (spectrum[inner] >= spectrum[inner - 1]) & (spectrum[inner] >= spectrum[inner + 1])
    ]
    strongest = peaks[np.argsort(spectrum[peaks])[::-1][:PEAKS_SCORED]]
    return strongest * bin_delay_s


def estimate_fsr(powers, frequency_hz, scale=None) -> FsrEstimate | None:
    """The FSR of the fringes in a sweep, from the readings alone (no design value).

    Parameters
    ----------
    powers : ndarray, shape (N, n)
        Validated port readings (W or any linear unit).
    frequency_hz : ndarray, shape (N,)
        Known frequencies (Hz), any order.
    scale : None or ndarray, shape (N,)
        Relative monitored source power per reading.

    Returns
    -------
    FsrEstimate or None
        None when the sweep has no span or the best fringe explains less than half of the
        readings' variance (no fringes above the noise).
    """
    powers = np.asarray(powers, dtype=float)
    frequency = np.asarray(frequency_hz, dtype=float)
    span = float(frequency.max() - frequency.min())
    unfitted = unfitted_cost(powers, scale)
    if not (span > 0 and unfitted > 0):
        return None
    relative = powers if scale is None else powers / scale[:, None]
    step = 1.0 / (PADDING * span)
    # below one fringe per sweep the periodogram has no resolution: score trial delays
    long_periods = np.arange(MIN_SPAN_FSR, 1.0, 1.0 / PADDING) / span
    trials = np.concatenate([_periodogram_delays(relative, frequency, span), long_periods])
    center = 0.5 * (frequency.max() + frequency.min())
    largest = float(trials.max()) + step
    if binning_pays(largest, span, powers.shape[0]):
        # one pass: J at every trial delay and in the refinement from the sweep's moments
        cost = FringeMoments(largest, center).add(frequency, powers, scale).cost
    else:  # fringes of a few readings each (noise peaks of the periodogram): fit directly

        def cost(delay_s: float) -> float:
            return map_cost(object_vectors(frequency, center, delay_s, scale), powers)[1]

    costs = [cost(delay) for delay in trials]
    start = float(trials[int(np.argmin(costs))])
    low = max(start - step, 0.5 * start)
    refined = optimize.minimize_scalar(
        cost, bounds=(low, start + step), method="bounded", options={"xatol": 1e-4 * step}
    )
    delay, best = (float(refined.x), float(refined.fun))
    if min(costs) < best:
        delay, best = start, float(min(costs))
    explained = 1.0 - best / unfitted
    if explained < MIN_EXPLAINED_FRACTION:
        return None
    return FsrEstimate(fsr_hz=1.0 / delay, delay_s=delay, explained=explained)


def _suggestion(estimate: FsrEstimate | None) -> str:
    if estimate is None:
        return (
            "the readings show no fringe period of their own to compare with (no fringes "
            "above the noise?); check fsr_hz and its unit (Hz)"
        )
    return (
        f"the sweep's own fringes repeat every {frequency_text(estimate.fsr_hz)}: set fsr_hz "
        f"to about {estimate.fsr_hz:.6g} Hz"
    )


def check_design_fsr(
    powers,
    frequency_hz,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    scale=None,
    step_hz: float | None = None,
    span_hz: float | None = None,
) -> FsrEstimate | None:
    """Refuse a design FSR the sweep cannot resolve, does not cover, or contradicts.

    Parameters
    ----------
    powers : ndarray, shape (N, n)
        Validated port readings: the sweep's, or a sample of them spread over it (every
        k-th reading), from which the sweep's own FSR is estimated.
    frequency_hz : ndarray, shape (N,)
        Known frequencies (Hz).
    fsr_hz : float
        Design FSR (Hz), already checked to be a finite number > 0.
    fsr_tolerance : float
        Relative half width of the bracket the fit will search.
    scale : None or ndarray, shape (N,)
        Relative monitored source power per reading.
    step_hz, span_hz : float, optional
        The whole sweep's median step and span (Hz) when the readings given are a sample of
        it; default: those of ``frequency_hz``.

    Returns
    -------
    FsrEstimate or None
        The sweep's own FSR (None when it shows no fringes), for diagnostics.

    Raises
    ------
    InputError
        With ``parameter="fsr_hz"``, stating the design value and the estimate.
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    span = float(frequency.max() - frequency.min()) if span_hz is None else span_hz
    estimate = estimate_fsr(powers, frequency, scale)
    design = f"the design FSR fsr_hz={fsr_hz:.6g} Hz ({frequency_text(fsr_hz)})"
    smallest = fsr_hz * (1.0 - fsr_tolerance)
    step = median_step_hz(frequency) if step_hz is None else step_hz
    if step >= 0.5 * smallest:
        raise InputError(
            f"{design} is not resolved by the sweep: its readings are {frequency_text(step)} "
            f"apart (median step), not below half the smallest FSR searched "
            f"({frequency_text(smallest)}), so a fringe would get fewer than 2 readings; "
            + _suggestion(estimate),
            parameter="fsr_hz",
        )
    if span < MIN_SPAN_FSR * fsr_hz:
        raise InputError(
            f"the sweep spans {span / 1e9:.6g} GHz, less than {MIN_SPAN_FSR:g} of the FSR "
            f"({fsr_hz / 1e9:.6g} GHz): sweep over at least "
            f"{MIN_SPAN_FSR * fsr_hz / 1e9:.6g} GHz, ideally a whole FSR; " + _suggestion(estimate),
            parameter="fsr_hz",
        )
    if estimate is not None:
        low = smallest / AGREEMENT_MARGIN
        high = fsr_hz * (1.0 + fsr_tolerance) * AGREEMENT_MARGIN
        if not low <= estimate.fsr_hz <= high:
            raise InputError(
                f"{design} is far from the FSR the sweep shows "
                f"({frequency_text(estimate.fsr_hz)}, explaining "
                f"{100 * estimate.explained:.4g} % of the fringe power): the search bracket "
                f"+-{100 * fsr_tolerance:g} % would not contain it; " + _suggestion(estimate),
                parameter="fsr_hz",
            )
    return estimate
