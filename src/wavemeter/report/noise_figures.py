"""Figures of a frequency-noise analysis: the series, its PSD, its Allan deviations.

Each function takes a :class:`~wavemeter.analysis.noise.FrequencyNoise` (and the series
for the first) and returns a :class:`matplotlib.figure.Figure` on the Agg canvas, without
pyplot; matplotlib is imported only when a figure is drawn. Axis labels carry their
units; confidence intervals are shaded bands; references (meter floor, beta separation
line) are drawn above the data.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..analysis.noise import beta_separation_line_hz2_per_hz
from ..units import FREQUENCY_UNITS
from .formatting import significant
from .plotting import (
    DATA_ZORDER,
    FIGURE_HEIGHT_IN,
    FIT_ZORDER,
    REFERENCE_ALPHA,
    REFERENCE_ZORDER,
    legend_outside,
    new_figure,
)

__all__ = [
    "plot_frequency_series",
    "plot_frequency_psd",
    "plot_allan_deviations",
    "noise_figures",
    "frequency_scale",
    "MAX_SERIES_POINTS",
]

#: above this many readings the series is drawn as block means with a min-max band
MAX_SERIES_POINTS = 4000
#: colour of each deviation in the Allan figure
DEVIATION_COLORS = {"adev": "tab:blue", "mdev": "tab:orange", "hdev": "tab:green"}
DEVIATION_NAMES = {"adev": "Allan (overlapping)", "mdev": "modified Allan", "hdev": "Hadamard"}


def frequency_scale(peak_hz: float) -> tuple[float, str]:
    """Display scale (Hz per unit) and unit for frequencies up to ``peak_hz``: the largest
    of Hz, kHz, MHz, GHz, THz not above it."""
    chosen = (1.0, "Hz")
    for unit, exponent in FREQUENCY_UNITS.items():
        if abs(peak_hz) >= 10.0**exponent:
            chosen = (10.0**exponent, unit)
    return chosen


def _blocks(values: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean, min and max of consecutive blocks of ``size`` values (NaN ignored; a block
    of NaN only gives NaN)."""
    padded = np.full(-(-values.size // size) * size, np.nan)
    padded[: values.size] = values
    blocks = padded.reshape(-1, size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks: NaN, drawn as gaps
        return np.nanmean(blocks, axis=1), np.nanmin(blocks, axis=1), np.nanmax(blocks, axis=1)


def plot_frequency_series(frequency_hz, rate_hz: float, center_hz: float):
    """Frequency against time, as offset from ``center_hz``; a long record as block means
    with the block's min-max range shaded (at most ``MAX_SERIES_POINTS`` blocks).

    Parameters
    ----------
    frequency_hz : array_like, shape (N,)
        The series (Hz); NaN readings (excluded) are gaps.
    rate_hz : float
        Sampling rate (Hz).
    center_hz : float
        The offset's origin (Hz).

    Returns
    -------
    matplotlib.figure.Figure
    """
    offset = np.asarray(frequency_hz, dtype=float) - center_hz
    finite = offset[np.isfinite(offset)]
    scale, unit = frequency_scale(np.max(np.abs(finite)) if finite.size else 1.0)
    block = max(1, -(-offset.size // MAX_SERIES_POINTS))
    figure, (axes,) = new_figure()
    if block == 1:
        time_s = np.arange(offset.size) / rate_hz
        axes.plot(time_s, offset / scale, "-", linewidth=0.6, color="tab:blue", label="reading")
    else:
        mean, low, high = _blocks(offset, block)
        time_s = (np.arange(mean.size) * block + (block - 1) / 2) / rate_hz
        axes.fill_between(
            time_s,
            low / scale,
            high / scale,
            color="tab:blue",
            alpha=REFERENCE_ALPHA,
            linewidth=0,
            zorder=DATA_ZORDER,
            label=f"min-max of {block} readings",
        )
        axes.plot(
            time_s,
            mean / scale,
            "-",
            linewidth=0.8,
            color="tab:blue",
            zorder=FIT_ZORDER,
            label=f"mean of {block} readings",
        )
    axes.set_xlabel("time (s)")
    axes.set_ylabel(f"frequency − {center_hz / 1e12:.6f} THz ({unit})")
    axes.set_title("Frequency of the readings")
    legend_outside(axes)
    return figure


def plot_frequency_psd(result):
    """The one-sided frequency-noise PSD with its confidence band, the meter's floor, the
    floor- and delay-corrected PSD, the fitted power law and the beta separation line.

    Parameters
    ----------
    result : FrequencyNoise

    Returns
    -------
    matplotlib.figure.Figure
    """
    freqs = np.asarray(result.psd_freqs_hz, dtype=float)
    psd = np.asarray(result.psd_hz2_per_hz, dtype=float)
    low, high = np.asarray(result.psd_ci_hz2_per_hz, dtype=float)
    corrected = np.asarray(result.psd_corrected_hz2_per_hz, dtype=float)
    figure, (axes,) = new_figure(height_in=FIGURE_HEIGHT_IN * 1.3)
    percent = significant(100 * result.confidence)
    axes.fill_between(
        freqs,
        low,
        high,
        color="tab:blue",
        alpha=REFERENCE_ALPHA,
        linewidth=0,
        zorder=DATA_ZORDER,
        label=f"{percent} % confidence",
    )
    axes.plot(freqs, psd, "-", color="tab:blue", zorder=FIT_ZORDER, label="measured")
    shown = np.isfinite(corrected) & (corrected > 0)
    if shown.any():
        axes.plot(
            freqs[shown],
            corrected[shown],
            "-",
            color="tab:purple",
            zorder=FIT_ZORDER,
            label="floor removed, delay corrected",
        )
    law = (
        result.white_fm_hz2_per_hz
        + result.flicker_fm_hz2 / freqs
        + result.random_walk_fm_hz2_per_s / freqs**2
    )
    if np.any(law > 0):
        axes.plot(
            freqs[law > 0],
            law[law > 0],
            "--",
            color="black",
            linewidth=1.0,
            zorder=REFERENCE_ZORDER,
            label="power-law fit h₀ + h₋₁/f + h₋₂/f²",
        )
    if result.meter_floor_hz2_per_hz is not None:
        axes.axhline(
            result.meter_floor_hz2_per_hz,
            color="tab:red",
            linestyle=":",
            zorder=REFERENCE_ZORDER,
            label="meter floor 2σ²/rate",
        )
    axes.plot(
        freqs,
        beta_separation_line_hz2_per_hz(freqs),
        "-.",
        color="tab:gray",
        zorder=REFERENCE_ZORDER,
        label="β separation line 8 ln2 f/π²",
    )
    if result.delay_correction_max_hz is not None and result.delay_correction_max_hz < freqs[-1]:
        axes.axvline(
            result.delay_correction_max_hz,
            color="tab:brown",
            linestyle=":",
            zorder=REFERENCE_ZORDER,
            label="delay correction limit",
        )
    floor = [] if result.meter_floor_hz2_per_hz is None else [result.meter_floor_hz2_per_hz]
    beta_top = beta_separation_line_hz2_per_hz(freqs[-1:])  # where the line matters most
    shown_values = np.concatenate([psd, high, corrected[shown], floor, beta_top])
    positive = shown_values[np.isfinite(shown_values) & (shown_values > 0)]
    if positive.size:  # the data, the floor and the beta line's top set the range
        axes.set_ylim(np.min(positive) / 3, np.max(positive) * 3)
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.set_xlabel("Fourier frequency f (Hz)")
    axes.set_ylabel("S_ν(f) (Hz²/Hz)")
    axes.set_title("Frequency-noise power spectral density (one-sided)")
    legend_outside(axes)
    return figure


def plot_allan_deviations(result):
    """Overlapping Allan, modified Allan and Hadamard deviations of fractional frequency
    against averaging time, each with its confidence band.

    Parameters
    ----------
    result : FrequencyNoise

    Returns
    -------
    matplotlib.figure.Figure
    """
    taus = np.asarray(result.taus_s, dtype=float)
    figure, (axes,) = new_figure(height_in=FIGURE_HEIGHT_IN * 1.3)
    percent = significant(100 * result.confidence)
    for name, color in DEVIATION_COLORS.items():
        values = np.asarray(getattr(result, name), dtype=float)
        low, high = np.asarray(getattr(result, f"{name}_ci"), dtype=float)
        axes.fill_between(taus, low, high, color=color, alpha=REFERENCE_ALPHA, linewidth=0)
        axes.plot(
            taus,
            values,
            "o-",
            markersize=3,
            color=color,
            zorder=FIT_ZORDER,
            label=f"{DEVIATION_NAMES[name]} ({percent} % band)",
        )
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.set_xlabel("averaging time τ (s)")
    axes.set_ylabel("deviation of y = (ν − ν₀)/ν₀ (dimensionless)")
    axes.set_title(f"Allan deviations, ν₀ = {result.center_frequency_hz / 1e12:.6f} THz")
    legend_outside(axes)
    return figure


def noise_figures(result, frequency_hz=None) -> dict:
    """The report's figures by name, in page order: ``frequency`` (when the series is
    given), ``psd``, ``allan`` (when there are averaging times)."""
    figures = {}
    if frequency_hz is not None:
        figures["frequency"] = plot_frequency_series(
            frequency_hz, result.rate_hz, result.center_frequency_hz
        )
    figures["psd"] = plot_frequency_psd(result)
    if len(result.taus_s):
        figures["allan"] = plot_allan_deviations(result)
    return figures
