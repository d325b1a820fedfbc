"""Analytic relations of power-law frequency noise: PSD, Allan family, regression slope.

A laser's frequency has the one-sided frequency-noise PSD (Hz^2/Hz)
``S_nu(f) = h0 + h_-1 / f + h_-2 / f^2`` (white, flicker and random-walk FM) plus a linear
drift ``D`` (Hz/s). This module gives the PSD (:func:`power_law_psd_hz2_per_hz`), the
expected Allan, modified Allan and Hadamard deviations of readings that are interval means
(:func:`power_law_deviations`, exact at every ``tau = m / rate`` through the phase's
structure function), the variance of a least-squares slope under that noise
(:func:`slope_variance`) and the expectation of a Welch estimate of each term
(:func:`welch_expectation`).

Theory (the structure function, the table of coefficients and its checks): the docs'
noise page (``docs/theory/noise.rst``, "Analytic relations of power-law noise").
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..validation import check_finite, check_non_negative, check_positive

__all__ = ["power_law_psd_hz2_per_hz", "power_law_deviations"]

#: noise terms in the order of every (3, ...) array here: white, flicker, random-walk FM
TERMS = ("white_fm_hz2_per_hz", "flicker_fm_hz2", "random_walk_fm_hz2_per_s")
#: large-n variance coefficients, AVAR/MVAR/HVAR * nu0^2 = coefficient * h * tau^exponent
_EXPONENTS = np.array([-1.0, 0.0, 1.0])
_COEFFICIENTS = {
    "adev": np.array([0.5, 2.0 * np.log(2.0), 2.0 * np.pi**2 / 3.0]),
    "mdev": np.array([0.25, 27.0 / 8.0 * np.log(3.0) - 4.0 * np.log(2.0), 11.0 / 20.0 * np.pi**2]),
    "hdev": np.array([0.5, 4.0 * np.log(2.0) - 1.5 * np.log(3.0), np.pi**2 / 3.0]),
}
#: drift coefficient, variance * nu0^2 = coefficient * (D tau)^2
_DRIFT = {"adev": 0.5, "mdev": 0.5, "hdev": 0.0}
#: from this many samples per tau on, the modified Allan variance is its large-n value
#: (the exact one differs by O(1/m^2): less than 1e-7)
EXACT_MDEV_LIMIT = 4096
#: largest relative distance of tau * rate from an integer
_INTEGER_TOLERANCE = 1e-6


def _levels(white_fm_hz2_per_hz, flicker_fm_hz2, random_walk_fm_hz2_per_s) -> np.ndarray:
    """The three levels (3,), checked finite and >= 0."""
    values = (white_fm_hz2_per_hz, flicker_fm_hz2, random_walk_fm_hz2_per_s)
    return np.array(
        [check_non_negative(name, value) for name, value in zip(TERMS, values, strict=True)]
    )


def _positive_vector(name: str, values) -> np.ndarray:
    try:
        array = np.array(values, dtype=float, ndmin=1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numbers, got {type(values).__name__}") from exc
    if array.ndim != 1 or not np.all(np.isfinite(array) & (array > 0)):
        raise InputError(
            f"{name} must be a vector of finite values > 0, got {values!r:.80}", parameter=name
        )
    return array


def psd_terms(freqs_hz: np.ndarray) -> np.ndarray:
    """The PSD of each term at unit level, ``(1, 1/f, 1/f^2)``, shape (3, K)."""
    return np.array([np.ones_like(freqs_hz), 1.0 / freqs_hz, 1.0 / freqs_hz**2])


def power_law_psd_hz2_per_hz(
    freqs_hz,
    *,
    white_fm_hz2_per_hz: float = 0.0,
    flicker_fm_hz2: float = 0.0,
    random_walk_fm_hz2_per_s: float = 0.0,
) -> np.ndarray:
    """One-sided frequency-noise PSD ``h0 + h_-1 / f + h_-2 / f^2`` (Hz^2/Hz).

    Parameters
    ----------
    freqs_hz : array_like, shape (K,)
        Fourier frequencies (Hz), > 0.
    white_fm_hz2_per_hz, flicker_fm_hz2, random_walk_fm_hz2_per_s : float
        ``h0`` (Hz^2/Hz), ``h_-1`` (Hz^2), ``h_-2`` (Hz^2/s), each >= 0.

    Returns
    -------
    ndarray, shape (K,), Hz^2/Hz

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.analysis import power_law_psd_hz2_per_hz
    >>> freqs_hz = np.array([1e2, 1e4, 1e6])
    >>> psd = power_law_psd_hz2_per_hz(freqs_hz, white_fm_hz2_per_hz=3e4, flicker_fm_hz2=1e9)
    >>> print(np.round(psd))  # flicker dominates at low frequency, white FM above 33 kHz
    [10030000.   130000.    31000.]
    """
    freqs = _positive_vector("freqs_hz", freqs_hz)
    levels = _levels(white_fm_hz2_per_hz, flicker_fm_hz2, random_walk_fm_hz2_per_s)
    return levels @ psd_terms(freqs)


def phase_structure(lags: np.ndarray, rate_hz: float) -> np.ndarray:
    """Generalised structure function ``D`` of the phase (cycles^2) at ``lags`` samples
    (integers >= 0), per unit level of each term, shape (3, K).

    The ``t^2 ln(tau0)`` part of flicker FM is left out: it cancels in every combination
    with ``sum c = sum c t = 0``, the only ones ``D`` is defined for.
    """
    lags = np.asarray(lags, dtype=float)
    tau0 = 1.0 / rate_hz
    with np.errstate(divide="ignore", invalid="ignore"):
        lag_log = np.where(lags > 0, lags**2 * np.log(np.where(lags > 0, lags, 1.0)), 0.0)
    return np.array(
        [
            0.5 * tau0 * lags,
            -(tau0**2) * lag_log,
            -(np.pi**2 / 3.0) * tau0**3 * lags**3,
        ]
    )


def reading_variogram(lags: np.ndarray, rate_hz: float) -> np.ndarray:
    """``E[(nu_{k+d} - nu_k)^2]`` (Hz^2) of readings that average the frequency over each
    sample interval, at lags ``d`` (integers >= 0), per unit level of each term, (3, K).

    White FM: ``h0 rate`` (``d >= 1``); random walk: ``2 pi^2 h_-2 (d - 1/3) / rate``;
    flicker: ``h_-1 (2 ln d + (d + 1)^2 ln(1 + 1/d) + (d - 1)^2 ln(1 - 1/d))``, written with
    ``log1p`` so that it keeps its precision at large ``d`` (it tends to ``2 ln d + 3``).
    """
    lags = np.asarray(lags, dtype=float)
    positive = lags > 0
    d = np.where(positive, lags, 2.0)  # placeholder where d = 0 (result set to 0 below)
    with np.errstate(divide="ignore", invalid="ignore"):
        below = np.where(d > 1, (d - 1.0) ** 2 * np.log1p(-1.0 / d), 0.0)
    flicker = 2.0 * np.log(d) + (d + 1.0) ** 2 * np.log1p(1.0 / d) + below
    terms = np.array(
        [
            np.full_like(d, rate_hz),
            flicker,
            2.0 * np.pi**2 * (d - 1.0 / 3.0) / rate_hz,
        ]
    )
    return np.where(positive, terms, 0.0)


def combination_variance(coefficients: np.ndarray, rate_hz: float) -> np.ndarray:
    """``Var(sum_j c_j x_j)`` (cycles^2) of phase samples ``x_j`` at ``j / rate``, per unit
    level of each term, shape (3,); ``c`` must have ``sum c = sum c j = 0``."""
    from scipy.signal import fftconvolve

    c = np.asarray(coefficients, dtype=float)
    # autocorrelation R(l) = sum_j c_j c_{j+l}, l >= 1; integer coefficients stay integers
    autocorrelation = np.rint(fftconvolve(c, c[::-1])[c.size :])
    lags = np.arange(1, c.size)
    return -(phase_structure(lags, rate_hz) @ autocorrelation)


def _modified_coefficients(m: int) -> np.ndarray:
    """Phase weights of the modified Allan variance's numerator at ``m`` samples,
    ``sum_{i<m} (x_{i+2m} - 2 x_{i+m} + x_i)``, length ``3m``."""
    second_difference = np.zeros(3 * m)
    second_difference[[0, m, 2 * m]] = (1.0, -2.0, 1.0)
    running = np.cumsum(second_difference)  # the sum over i < m: a running sum of m terms
    return running - np.concatenate((np.zeros(m), running[:-m]))


def _averaging_factors(taus: np.ndarray, rate_hz: float) -> np.ndarray:
    factors = np.rint(taus * rate_hz)
    if np.any(factors < 1) or np.any(
        np.abs(taus * rate_hz - factors) > _INTEGER_TOLERANCE * factors
    ):
        raise InputError(
            f"taus_s must be whole multiples of the sample interval 1 / rate_hz = "
            f"{1.0 / rate_hz:.6g} s, got {taus!r:.80}",
            parameter="taus_s",
        )
    return factors.astype(np.int64)


def deviation_variances(
    taus_s: np.ndarray, levels: np.ndarray, drift_hz_per_s: float, rate_hz: float | None
) -> dict[str, np.ndarray]:
    """Variance contributions (Hz^2, not yet divided by ``nu0^2``) of white, flicker,
    random-walk FM and drift to AVAR, MVAR and HVAR at each tau: ``{name: (4, M)}``."""
    taus = np.asarray(taus_s, dtype=float)
    result = {}
    for name, coefficients in _COEFFICIENTS.items():
        terms = coefficients[:, None] * levels[:, None] * taus[None, :] ** _EXPONENTS[:, None]
        drift = _DRIFT[name] * (drift_hz_per_s * taus) ** 2
        result[name] = np.vstack([terms, drift])
    if rate_hz is not None:
        for index, m in enumerate(_averaging_factors(taus, rate_hz)):
            if m >= EXACT_MDEV_LIMIT:
                continue
            variance = combination_variance(_modified_coefficients(int(m)), rate_hz)
            result["mdev"][:3, index] = levels * variance / (2.0 * m**2 * taus[index] ** 2)
    return result


def power_law_deviations(
    taus_s,
    center_hz: float,
    *,
    white_fm_hz2_per_hz: float = 0.0,
    flicker_fm_hz2: float = 0.0,
    random_walk_fm_hz2_per_s: float = 0.0,
    drift_hz_per_s: float = 0.0,
    rate_hz: float | None = None,
) -> dict[str, np.ndarray]:
    """Analytic Allan, modified Allan and Hadamard deviations of fractional frequency.

    Variances of the independent terms add (see the module's table).

    Parameters
    ----------
    taus_s : array_like, shape (M,)
        Averaging times (s), > 0.
    center_hz : float
        Laser frequency ``nu0`` (Hz), > 0: the deviations are of ``(nu - nu0) / nu0``.
    white_fm_hz2_per_hz, flicker_fm_hz2, random_walk_fm_hz2_per_s : float
        ``h0`` (Hz^2/Hz), ``h_-1`` (Hz^2), ``h_-2`` (Hz^2/s) of ``S_nu``, each >= 0.
    drift_hz_per_s : float
        Linear drift ``D`` (Hz/s).
    rate_hz : float, optional
        Sample rate (Hz) of readings that are each the mean frequency over their sample
        interval: the modified Allan deviation is then exact at every ``tau = m / rate``
        (``taus_s`` must be such multiples; from ``m = EXACT_MDEV_LIMIT`` on, within
        1e-7). None: its large-``n`` limit. The Allan and
        Hadamard deviations are the same either way.

    Returns
    -------
    dict
        ``{"adev", "mdev", "hdev"}``: arrays (M,), dimensionless.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.analysis import power_law_deviations
    >>> taus_s = np.array([1e-6, 1e-4])
    >>> dev = power_law_deviations(taus_s, 193.4e12, white_fm_hz2_per_hz=3e4)
    >>> sorted(dev)
    ['adev', 'hdev', 'mdev']

    White FM: AVAR = h0 / (2 tau) / nu0^2, falling as tau^-1/2:

    >>> print([f"{value:.2e}" for value in dev["adev"]])
    ['6.33e-10', '6.33e-11']
    >>> print(np.allclose(dev["adev"], np.sqrt(3e4 / (2 * taus_s)) / 193.4e12))
    True
    """
    taus = _positive_vector("taus_s", taus_s)
    center = check_positive("center_hz", center_hz)
    levels = _levels(white_fm_hz2_per_hz, flicker_fm_hz2, random_walk_fm_hz2_per_s)
    drift = check_finite("drift_hz_per_s", drift_hz_per_s)
    rate = None if rate_hz is None else check_positive("rate_hz", rate_hz)
    variances = deviation_variances(taus, levels, drift, rate)
    return {name: np.sqrt(terms.sum(axis=0)) / center for name, terms in variances.items()}


def slope_variance(samples: int, rate_hz: float, levels: np.ndarray) -> float:
    """Variance (Hz^2/s^2) of the least-squares slope of ``samples`` readings at
    ``rate_hz`` with power-law noise of ``levels`` (3,).

    ``6 h0 / T^3 + 9 h_-1 / T^2 + (12 pi^2 / 5) h_-2 / T`` (``T`` the record length; the
    white term exact for ``samples``), negative levels counted as 0. Derivation: the docs'
    noise page (``docs/theory/noise.rst``, "The power-law fit and the linewidths", drift).
    """
    duration_s = samples / rate_hz
    gains = np.array(
        [
            6.0 * rate_hz**3 / (samples**3 - samples),
            9.0 / duration_s**2,
            12.0 * np.pi**2 / 5.0 / duration_s,
        ]
    )
    return float(gains @ np.maximum(levels, 0.0))


def welch_expectation(window: np.ndarray, rate_hz: float) -> np.ndarray:
    """Expected one-sided Welch PSD (Hz^2/Hz, ``scipy.signal.welch``'s density with a
    linear detrend per segment) of each term at unit level, bins ``0..L/2`` of segments
    windowed by ``window`` (L,), shape (3, L/2 + 1).

    A segment's bin ``k`` is ``X_k = c^T nu`` with ``c = (I - P)(w e_k)`` (``P`` projects
    on the line the detrend removes, ``e_k`` the bin's complex exponential), and ``sum c =
    0``, so ``E|X_k|^2 = -1/2 c^H V c`` with ``V`` the readings' variogram
    (:func:`reading_variogram`): exact at every bin, the window's leakage, the detrend and
    the sample-interval means included. ``c^H V c`` takes a few FFTs and two Toeplitz
    products (``scipy.linalg.matmul_toeplitz``). (Bins 0 and ``L/2`` are not doubled by
    ``welch``; they are left as computed, unused.)"""
    from scipy.linalg import matmul_toeplitz

    length = window.size
    lags = np.arange(length)
    overlap = np.fft.irfft(np.abs(np.fft.rfft(window, 2 * length)) ** 2)[:length]
    ramp = lags - lags.mean()
    basis = (np.full(length, length**-0.5), ramp / np.linalg.norm(ramp))
    expectations = []
    for variogram in reading_variogram(lags, rate_hz):
        weighted = variogram * overlap
        folded = weighted + np.concatenate(([0.0], weighted[:0:-1]))
        quadratic = np.fft.rfft(folded).real
        projected = [np.fft.rfft(q * window) for q in basis]  # q^T u_k
        applied = [matmul_toeplitz(variogram, q) for q in basis]
        cross = [np.fft.rfft(window * v) for v in applied]  # conj(u_k^H V q)
        gram = np.array([[p @ v for v in applied] for p in basis])
        alpha, beta = projected
        total = (
            quadratic
            - 2.0 * (alpha * cross[0].conj() + beta * cross[1].conj()).real
            + np.abs(alpha) ** 2 * gram[0, 0]
            + 2.0 * (alpha.conj() * beta).real * gram[0, 1]
            + np.abs(beta) ** 2 * gram[1, 1]
        )
        expectations.append(-total / (rate_hz * np.sum(window**2)))  # 2 * (-1/2) * ...
    return np.array(expectations)
