"""A laser whose frequency wanders with power-law noise and drift, sampled at a rate.

:func:`laser_frequency_hz` draws readings of a laser with the one-sided frequency-noise PSD
``S_nu(f) = h0 + h_-1 / f + h_-2 / f^2`` (Hz^2/Hz; white, flicker and random-walk FM) plus
a linear drift. Reading ``k`` is the laser's mean frequency over ``[k, k + 1] / rate`` (a
counter with a gate of one sample), so the Allan family of the readings is exactly that of
the continuous-time laser (:func:`wavemeter.analysis.power_law_deviations`). Flicker FM is
shaped in the frequency domain to the exact PSD of interval means over
``FLICKER_OVERSPAN`` times the record; each term draws from its own stream spawned from
``rng``.

Theory (how each term is drawn): the docs' noise page (``docs/theory/noise.rst``,
"Simulated lasers").
"""

from __future__ import annotations

import numpy as np

from ..validation import as_rng, check_finite, check_non_negative, check_positive
from .drift import _check_samples

__all__ = ["laser_frequency_hz"]

#: the flicker noise is drawn over this many record lengths, of which the first is kept
FLICKER_OVERSPAN = 4


def _flicker_hz(samples: int, rate_hz: float, level: float, rng) -> np.ndarray:
    """Interval means of flicker FM of level ``level`` (Hz^2), (samples,) Hz."""
    from scipy.fft import irfft, next_fast_len, rfft
    from scipy.special import zeta

    length = next_fast_len(FLICKER_OVERSPAN * samples, real=True)
    spectrum = rfft(rng.standard_normal(length))
    x = np.arange(1, spectrum.size) / length  # cycles per sample, (0, 1/2]
    psd = level / (np.pi**2 * rate_hz) * np.sin(np.pi * x) ** 2 * (zeta(3, x) + zeta(3, 1 - x))
    # unit white noise has the one-sided PSD 2 / rate: scale each bin to the target PSD
    spectrum[0] = 0.0
    spectrum[1:] *= np.sqrt(psd * rate_hz / 2.0)
    return irfft(spectrum, n=length)[:samples]


def _random_walk_hz(samples: int, rate_hz: float, level: float, rng) -> np.ndarray:
    """Interval means of random-walk FM of level ``level`` (Hz^2/s), (samples,) Hz."""
    step_variance = 2.0 * np.pi**2 * level / rate_hz
    ends = np.concatenate(([0.0], np.cumsum(rng.normal(0.0, np.sqrt(step_variance), samples))))
    bridge = rng.normal(0.0, np.sqrt(step_variance / 12.0), samples)
    return 0.5 * (ends[:-1] + ends[1:]) + bridge


def laser_frequency_hz(
    samples: int,
    rate_hz: float,
    *,
    center_hz: float,
    white_fm_hz2_per_hz: float = 0.0,
    flicker_fm_hz2: float = 0.0,
    random_walk_fm_hz2_per_s: float = 0.0,
    drift_hz_per_s: float = 0.0,
    rng=None,
) -> np.ndarray:
    """Frequency readings (Hz) of a laser with power-law frequency noise and drift.

    Parameters
    ----------
    samples : int
        Readings ``N`` (>= 1).
    rate_hz : float
        Sample rate (Hz), > 0; reading ``k`` is the mean frequency over
        ``[k, k + 1] / rate_hz``.
    center_hz : float
        Laser frequency at ``t = 0`` (Hz), > 0: the mean of the white and flicker terms,
        where the random walk and the drift start.
    white_fm_hz2_per_hz : float
        ``h0`` (Hz^2/Hz), >= 0: the Lorentzian linewidth (FWHM) is ``pi h0``.
    flicker_fm_hz2 : float
        ``h_-1`` (Hz^2), >= 0.
    random_walk_fm_hz2_per_s : float
        ``h_-2`` (Hz^2/s = Hz^3), >= 0.
    drift_hz_per_s : float
        Linear drift ``D`` (Hz/s), any sign.
    rng : None, int or numpy.random.Generator
        Source of the noise.

    Returns
    -------
    ndarray, shape (N,), Hz
        To pass as the frequencies of
        :meth:`Interferometer.powers <wavemeter.simulation.Interferometer.powers>`.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.simulation import laser_frequency_hz
    >>> rate_hz, h0 = 1e6, 1e4  # readings at 1 MHz, white FM of 1e4 Hz^2/Hz
    >>> f_hz = laser_frequency_hz(4096, rate_hz, center_hz=193.4e12, white_fm_hz2_per_hz=h0, rng=1)

    White FM of level h0 gives readings of variance h0 rate / 2 (a 71 kHz std here):

    >>> expected_hz = np.sqrt(h0 * rate_hz / 2)
    >>> print(f"std {np.std(f_hz) / 1e3:.0f} kHz, expected {expected_hz / 1e3:.0f} kHz")
    std 70 kHz, expected 71 kHz
    """
    samples = _check_samples(samples)
    rate_hz = check_positive("rate_hz", rate_hz)
    center_hz = check_positive("center_hz", center_hz)
    white = check_non_negative("white_fm_hz2_per_hz", white_fm_hz2_per_hz)
    flicker = check_non_negative("flicker_fm_hz2", flicker_fm_hz2)
    walk = check_non_negative("random_walk_fm_hz2_per_s", random_walk_fm_hz2_per_s)
    drift = check_finite("drift_hz_per_s", drift_hz_per_s)
    white_rng, flicker_rng, walk_rng = as_rng(rng).spawn(3)
    times_s = (np.arange(samples) + 0.5) / rate_hz
    frequency_hz = center_hz + drift * times_s
    if white > 0:
        frequency_hz += white_rng.normal(0.0, np.sqrt(white * rate_hz / 2.0), samples)
    if flicker > 0:
        frequency_hz += _flicker_hz(samples, rate_hz, flicker, flicker_rng)
    if walk > 0:
        frequency_hz += _random_walk_hz(samples, rate_hz, walk, walk_rng)
    return frequency_hz
