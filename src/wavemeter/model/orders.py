"""Fringe orders across a cascade: how likely a stage hands the next one the wrong order.

A stage of FSR ``F`` knows frequency modulo ``F``; the stage before it, of frequency error
``e1`` (std ``s1``), picks the order whose frequency lies nearest its own estimate. With the
finer stage's own error ``e2`` (std ``s2``), the observed hand-over residual (coarse
estimate minus the fine one at the chosen order) is ``r = e1 - e2 + m F`` for a true order
``m`` away from the chosen one, ``e1 - e2 ~ N(0, s^2)``, ``s^2 = s1^2 + s2^2``. With every
order equally likely beforehand (frequency uniform over many FSRs), the posterior
probability that the chosen order is wrong is

    P(wrong | r) = sum_{m != 0} w_m / sum_m w_m,   w_m = exp(-(r - m F)^2 / (2 s^2)),

and its mean over readings is the wrong-order rate ``P(|e1 - e2| > F / 2) = erfc(F /
(2 sqrt(2) s))``.

The coarsest stage has no stage before it: its phase is unique over a range of one period
``F0`` about the band's middle, wider than the band, and its order is wrong when a reading
near an end of the band comes out past the end of that range (it wraps to the other end).
A reading at distance ``d`` inside an end of the range lies beyond it with probability
``Q(d / s) = erfc(d / (sqrt(2) s)) / 2`` (every frequency equally likely); with the truth
known to lie in the band ``[low, high]`` (uniformly), the posterior probability of a wrap
for an estimate ``f`` is ``M(F0) + M(-F0)`` over ``M(0) + M(F0) + M(-F0)``, where
``M(shift)`` is the normal probability of ``[low, high]`` about ``f + shift``.
"""

from __future__ import annotations

import numpy as np
from scipy import special

__all__ = [
    "ALTERNATIVE_ORDERS",
    "handover_error_probability",
    "handover_error_rate",
    "edge_error_probability",
    "wrap_error_probability",
    "any_error_probability",
]

#: orders either side of the chosen one the posterior weighs (beyond, w_m < w_3 everywhere
#: the probability is below 1/2)
ALTERNATIVE_ORDERS = 3


def handover_error_probability(residual_hz, fsr_hz, std_hz) -> np.ndarray:
    """Posterior probability that a hand-over picked the wrong order (module docstring).

    Parameters
    ----------
    residual_hz : array_like, shape (N,)
        Coarse estimate minus the fine one at the order chosen (Hz), within ``+- fsr_hz/2``.
    fsr_hz : float or array_like, shape (N,)
        The fine stage's (local) FSR (Hz).
    std_hz : float or array_like, shape (N,)
        Standard deviation ``s`` of the residual (Hz): both stages' errors combined.

    Returns
    -------
    ndarray, shape (N,)
        Probability in [0, 1); 0 where ``std_hz`` is 0.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.model import handover_error_probability
    >>> residual_hz = np.array([0.0, 10e9, 20e9])  # coarse minus fine at the chosen order
    >>> p = handover_error_probability(residual_hz, 50e9, 5e9)  # a 50 GHz fine FSR, 5 GHz std
    >>> print([f"{value:.1e}" for value in p])  # far likelier wrong near half an FSR
    ['3.9e-22', '9.4e-14', '4.5e-05']
    """
    residual = np.asarray(residual_hz, dtype=float)
    fsr = np.asarray(fsr_hz, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(np.asarray(std_hz) > 0, 1.0 / np.square(std_hz), np.inf)
    others = np.zeros(np.broadcast(residual, fsr, scale).shape)
    for order in range(-ALTERNATIVE_ORDERS, ALTERNATIVE_ORDERS + 1):
        if order:
            # log(w_m / w_0) = -(m^2 F^2 - 2 m r F) / (2 s^2) <= 0 for |r| <= F/2
            exponent = -(order * fsr * (order * fsr - 2.0 * residual)) * scale / 2.0
            others += np.exp(np.where(np.isfinite(exponent), exponent, -np.inf))
    return others / (1.0 + others)


def handover_error_rate(fsr_hz, std_hz) -> np.ndarray:
    """Expected wrong-order rate of a hand-over: ``erfc(F / (2 sqrt(2) s))`` (the mean of
    :func:`handover_error_probability` over readings).

    Examples
    --------
    >>> from wavemeter.model import handover_error_rate
    >>> for std_hz in (2e9, 5e9):  # residual std of a hand-over to a 50 GHz stage
    ...     print(f"{handover_error_rate(50e9, std_hz):.1e}")
    7.5e-36
    5.7e-07
    """
    return special.erfc(np.asarray(fsr_hz, dtype=float) / (2.0 * np.sqrt(2.0) * np.asarray(std_hz)))


def edge_error_probability(distance_hz, std_hz) -> np.ndarray:
    """Probability ``Q(d / s)`` that a reading estimated ``distance_hz`` inside an end of the
    unique range lies beyond it (the coarsest stage's order is then wrong).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.model import edge_error_probability
    >>> print(edge_error_probability(np.array([1e9, 3e9]), 1e9))  # 1 and 3 std inside the edge
    [0.15865525 0.0013499 ]
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(distance_hz, dtype=float) / (np.sqrt(2.0) * np.asarray(std_hz))
    return 0.5 * special.erfc(ratio)


def _band_mass(center_hz, std_hz, low_hz: float, high_hz: float) -> np.ndarray:
    """Normal probability (mean ``center_hz``, std ``std_hz``) of ``[low_hz, high_hz]``, with
    both tails' precision (the upper tail is taken from the other side)."""
    lower = (low_hz - center_hz) / std_hz
    upper = (high_hz - center_hz) / std_hz
    return np.where(
        lower > 0,
        special.ndtr(-lower) - special.ndtr(-upper),
        special.ndtr(upper) - special.ndtr(lower),
    )


def wrap_error_probability(frequency_hz, std_hz, band_hz, period_hz) -> np.ndarray:
    """Posterior probability that the coarsest stage's estimate wrapped (module docstring).

    Parameters
    ----------
    frequency_hz : array_like, shape (N,)
        The coarsest stage's estimate (Hz).
    std_hz : array_like, shape (N,)
        Its standard deviation (Hz), > 0.
    band_hz : (float, float)
        The band the truth lies in (Hz), narrower than ``period_hz``.
    period_hz : float or array_like, shape (N,)
        The range the stage's phase is unique over (its FSR, Hz).

    Returns
    -------
    ndarray, shape (N,)
        In [0, 1]; 1 where the estimate lies so far outside the band that neither it nor
        its wrapped twin has any probability there (the order is then unknown).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.model import wrap_error_probability
    >>> band_hz = (191e12, 196e12)  # the C band, read by a 6 THz coarse stage
    >>> estimate_hz = np.array([193.5e12, 196.2e12, 190.3e12])  # mid band, just beyond its edges
    >>> print(np.round(wrap_error_probability(estimate_hz, 0.3e12, band_hz, 6e12), 3))
    [0.    0.015 0.942]
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    std = np.asarray(std_hz, dtype=float)
    period = np.asarray(period_hz, dtype=float)
    low, high = band_hz
    inside = _band_mass(frequency, std, low, high)
    wrapped = _band_mass(frequency + period, std, low, high) + _band_mass(
        frequency - period, std, low, high
    )
    total = inside + wrapped
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total > 0, wrapped / total, 1.0)


def any_error_probability(probabilities) -> np.ndarray:
    """``1 - prod_k (1 - p_k)`` over the first axis: some stage's order is wrong (accurate
    for tiny ``p_k``).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.model import any_error_probability
    >>> stages = np.array([[1e-9, 1e-3], [2e-9, 1e-3]])  # two stages (rows), two readings
    >>> print(any_error_probability(stages))
    [3.000e-09 1.999e-03]
    """
    stacked = np.asarray(probabilities, dtype=float)
    # a p_k of 1 (a reading far outside the band) gives log1p(-1) = -inf and 1 exactly
    with np.errstate(divide="ignore"):
        logs = np.log1p(-stacked)
    # + 0.0: no -0.0 where every p_k is 0
    return -np.expm1(np.sum(logs, axis=0)) + 0.0
