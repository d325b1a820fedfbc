"""The band-averaged Welch PSD of a meter's readings, its degrees of freedom and band
correlations, its confidence interval, and its correction for the meter's floor and delay.

- PSD: ``scipy.signal.welch`` (Hann window, 50 % overlap, linear detrend per segment,
  one-sided density) with segments of the largest power of two <= ``N / 8`` samples (at
  least ``MIN_SEGMENT``), so it reaches down to 16 to 32 over the record length ``T``.
  The bins from the second (``FIRST_BIN``; the first is halved by the detrend) to below
  Nyquist are averaged in ``BANDS_PER_DECADE`` log-spaced bands, so high frequencies have
  many degrees of freedom. A band's equivalent degrees of freedom ``nu = 2 / v`` come
  from the window: ``v`` is the variance of the band mean relative to its square for a
  spectrum locally white over the band, ``sum_d sum_Delta (K - |d|) (M - |Delta|) |C(d s,
  Delta)|^2 / (K M)^2`` over segment offsets ``d`` (step ``s``) and bin offsets ``Delta``
  of the ``K`` segments and ``M`` bins, ``C`` the window's normalised overlap spectrum
  (Welch 1967; the detrend's two lost degrees of freedom per segment are neglected). Bins
  more than ``BIN_SPREAD`` apart are uncorrelated, so only neighbouring bands correlate.
  The confidence interval at ``confidence`` is chi-square with ``nu`` degrees of freedom.
- Delay: the interferometer's delay ``tau_d = 1 / FSR`` averages the frequency over
  ``tau_d``, ``|H(f)|^2 = sinc^2(f / FSR)``. The corrected PSD is ``(PSD - floor) /
  sinc^2(f / FSR)`` up to ``DELAY_CORRECTION_MAX_FSR`` of the FSR (where ``|H|^2 >=
  0.81``) and NaN above, excluded from the fits. The detectors' bandwidth and any
  anti-aliasing filter are not corrected: the readings are taken as sample-interval means.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .power_law import welch_expectation

#: Welch segments: the largest power of two <= N / SEGMENT_DIVISOR, and >= MIN_SEGMENT
SEGMENT_DIVISOR = 8
MIN_SEGMENT = 32
#: first Welch bin used (the first is halved by the per-segment linear detrend)
FIRST_BIN = 2
#: log-spaced PSD bands per decade of frequency
BANDS_PER_DECADE = 20
#: Welch bins further apart than this are uncorrelated (Hann: |C|^2 < 1e-6 beyond)
BIN_SPREAD = 8
#: the PSD is corrected for the delay's sinc^2 up to this fraction of the FSR
DELAY_CORRECTION_MAX_FSR = 0.25


def _segment_length(samples: int) -> int:
    longest = max(samples // SEGMENT_DIVISOR, 1)
    return max(1 << (longest.bit_length() - 1), MIN_SEGMENT)


def band_covariance(
    window: np.ndarray, step: int, segments: int, first_bins: np.ndarray, widths: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Equivalent degrees of freedom (K,) and correlation matrix (K, K) of the band means
    of a locally white spectrum (see the module's notes)."""
    length = window.size
    norm = np.sum(window**2)
    # kernel(Delta) = sum over segment pairs of |C(d s, Delta)|^2, Delta = 0..BIN_SPREAD
    kernel = np.zeros(BIN_SPREAD + 1)
    for d, shift in enumerate(range(0, min(length, segments * step), step)):
        pairs = segments if d == 0 else 2 * (segments - d)
        overlap = np.fft.fft(window[: length - shift] * window[shift:], length)
        kernel += pairs * np.abs(overlap[: BIN_SPREAD + 1]) ** 2 / norm**2
    bands = widths.size
    covariance = np.zeros((bands, bands))
    ends = first_bins + widths
    for a in range(bands):
        offsets = np.arange(-min(widths[a] - 1, BIN_SPREAD), min(widths[a], BIN_SPREAD + 1))
        covariance[a, a] = (widths[a] - np.abs(offsets)) @ kernel[np.abs(offsets)]
        for b in range(a + 1, bands):
            if first_bins[b] - (ends[a] - 1) > BIN_SPREAD:
                break
            offsets = np.arange(first_bins[b] - ends[a] + 1, BIN_SPREAD + 1)
            counts = np.minimum(ends[a], ends[b] - offsets) - np.maximum(
                first_bins[a], first_bins[b] - offsets
            )
            covariance[a, b] = covariance[b, a] = np.clip(counts, 0, None) @ kernel[offsets]
    scale = np.sqrt(np.diag(covariance))
    dof = 2.0 * (segments * widths) ** 2 / np.diag(covariance)
    return dof, covariance / np.outer(scale, scale)


@dataclass(frozen=True)
class Spectrum:
    """The Welch PSD of a series averaged over log-spaced bands, with what its fits need."""

    freqs_hz: np.ndarray  # band mean frequency (K,)
    psd: np.ndarray  # band mean Welch PSD (K,)
    dof: np.ndarray  # (K,)
    correlation: np.ndarray  # of the band means (K, K)
    design: np.ndarray  # expected band PSD of each term at unit level, delay applied (K, 3)
    floor_gain: np.ndarray  # expected band PSD of unit white meter noise (K,)
    edges_hz: np.ndarray  # band edges (K + 1,)


def welch_bands(series: np.ndarray, rate_hz: float, fsr_hz: float | None) -> Spectrum:
    """The band spectrum of ``series`` (N,) sampled at ``rate_hz`` (Hz), the expectations
    of its terms passed through the delay ``1 / fsr_hz`` (none when None)."""
    from scipy.signal import get_window, welch

    length = _segment_length(series.size)
    step = length // 2
    window = get_window("hann", length)
    bin_freqs, psd = welch(
        series, fs=rate_hz, window=window, noverlap=length - step, detrend="linear"
    )
    segments = (series.size - length) // step + 1
    expected = welch_expectation(window, rate_hz)
    bins = np.arange(FIRST_BIN, length // 2)
    band_of_bin = np.floor(BANDS_PER_DECADE * np.log10(bins / FIRST_BIN) + 1e-9).astype(int)
    starts = np.flatnonzero(np.diff(np.concatenate(([-1], band_of_bin))))
    widths = np.diff(np.concatenate((starts, [bins.size])))
    delay = np.ones_like(bin_freqs) if fsr_hz is None else np.sinc(bin_freqs / fsr_hz) ** 2

    def band_mean(values: np.ndarray) -> np.ndarray:
        return np.add.reduceat(values[..., bins], starts, axis=-1) / widths

    resolution = rate_hz / length
    first_bins = bins[starts]
    edges = np.concatenate((first_bins, [bins[-1] + 1])) - 0.5
    dof, correlation = band_covariance(window, step, segments, first_bins, widths)
    return Spectrum(
        freqs_hz=band_mean(bin_freqs),
        psd=band_mean(psd),
        dof=dof,
        correlation=correlation,
        design=band_mean(expected * delay).T,
        floor_gain=band_mean(expected[0]),
        edges_hz=edges * resolution,
    )


def psd_interval(spectrum: Spectrum, confidence: float) -> np.ndarray:
    """Chi-square confidence interval (2, K), [lower, upper] (Hz^2/Hz), of the band PSD."""
    from scipy.stats import chi2 as chi_square

    tail = (1.0 - confidence) / 2.0
    return spectrum.dof * spectrum.psd / chi_square.ppf([[1.0 - tail], [tail]], spectrum.dof)


def delay_correction(
    spectrum: Spectrum, floor: float | None, fsr_hz: float | None
) -> tuple[np.ndarray, np.ndarray, float | None]:
    """The laser's band PSD (K,) (Hz^2/Hz): the floor subtracted (none when None), divided
    by the delay's ``sinc^2(f / fsr_hz)`` at the bands (K,), NaN above the correction's
    limit ``DELAY_CORRECTION_MAX_FSR * fsr_hz`` (Hz; None without an FSR); all three."""
    if fsr_hz is None:
        delay_band, limit_hz = np.ones_like(spectrum.freqs_hz), None
    else:
        delay_band = np.sinc(spectrum.freqs_hz / fsr_hz) ** 2
        limit_hz = DELAY_CORRECTION_MAX_FSR * fsr_hz
    corrected = (spectrum.psd - (floor or 0.0)) / delay_band
    if limit_hz is not None:
        corrected[spectrum.freqs_hz > limit_hz] = np.nan
    return corrected, delay_band, limit_hz
