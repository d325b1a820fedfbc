"""A laser whose frequency wanders with power-law noise and drift, sampled at a rate.

The laser's frequency has the one-sided frequency-noise PSD (Hz^2/Hz)

    S_nu(f) = h0 + h_-1 / f + h_-2 / f^2

(``h0`` white FM, ``h_-1`` flicker FM, ``h_-2`` random-walk FM) plus a linear drift.
Reading ``k`` is the laser's mean frequency over its sample interval ``[k, k + 1] / rate``
(a frequency counter with a gate of one sample): the Allan family of the readings is then
exactly that of the continuous-time laser at every ``tau = m / rate``
(:func:`wavemeter.analysis.power_law_deviations`), and their PSD is ``S_nu`` at
frequencies well below the rate (above, the averaging's ``sinc^2`` and aliasing shape it;
white FM stays flat at ``h0``).

- White FM: independent normal readings of variance ``h0 rate / 2`` (the mean of white
  noise of level ``h0`` over ``1 / rate``).
- Random walk: a Wiener process with steps of variance ``Dv / rate`` per sample
  (``Dv = 2 pi^2 h_-2``, since a random walk growing by ``Dv`` per second has the PSD
  ``Dv / (2 pi^2 f^2)``), summed from 0 at ``t = 0``; a reading is the mean of its two
  ends plus the Brownian bridge's own mean over the interval (variance ``Dv / (12
  rate)``), so that it is the exact interval mean.
- Flicker FM: white noise shaped in the frequency domain (``numpy.fft``) to the exact
  PSD of interval means of ``h_-1 / f``, ``(h_-1 / (pi^2 rate)) sin^2(pi x) (zeta(3, x) +
  zeta(3, 1 - x))`` at ``x = f / rate`` (Hurwitz zeta: the aliases ``f + j rate`` summed
  with their ``sinc^2``), over four times the record, of which the first quarter is kept
  (so the record is not periodic and keeps its slowest fluctuations). (allantools' Kasdin
  generator draws from numpy's global random state and has the discrete PSD ``h_-1 pi /
  (rate sin(pi x))``, equal to ``h_-1 / f`` only well below the rate; this one follows
  ``rng``.)
- Drift ``D``: ``D t`` at the interval's middle, ``t = (k + 1/2) / rate``.

Each term draws from its own stream spawned from ``rng``, so a seed gives the same white
noise whatever the other levels are.
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
