"""Figures of a calibration's errors, after the paper's Figs. 4, 7 and 8, and of a wide-band
calibration's orders and residual phase; arrays in.

Each function returns a :class:`matplotlib.figure.Figure` drawn on the Agg canvas, without
pyplot (no global state, no window). Matplotlib is imported only when a figure is made, so
``import wavemeter`` does not import it. Every axis label carries its unit in parentheses;
legends sit outside the data area; references (ideal line, correct circle, Cramer-Rao
band) are drawn above the data. The fringe figures are in :mod:`.fringes`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..calibration.contract.figures import FigureData
from .formatting import frequency_error_unit, significant
from .plotting import (
    DATA_ZORDER,
    FIGURE_HEIGHT_IN,
    MARKER_ALPHA,
    MARKER_SIZE,
    REFERENCE_ALPHA,
    REFERENCE_ZORDER,
    legend_outside,
    method_color,
    new_figure,
    offset_label,
    thin,
)

__all__ = [
    "plot_object_space",
    "plot_retrieved_frequency",
    "plot_residuals",
    "plot_error_histogram",
    "plot_error_against_temperature",
    "plot_figure_data",
    "CIRCLE_POINTS",
]

CIRCLE_POINTS = 361
#: a residual phase whose largest value is below this (rad) is shown in mrad
MRAD_BELOW_RAD = 0.1
#: marker size of the chosen candidate, ringed, in the cross-validation curve
CHOSEN_MARKER_SIZE = 12


def _markers(axes, x, y, color: str, label: str) -> None:
    axes.plot(
        x,
        y,
        "o",
        markersize=MARKER_SIZE,
        alpha=MARKER_ALPHA,
        color=color,
        zorder=DATA_ZORDER,
        label=label,
    )


def plot_object_space(samples: Mapping[str, np.ndarray]):
    """Object-space samples on the unit-power section of the cone: paper Fig. 4a.

    Each sample ``x = P [cos t, sin t, sqrt 2]`` is shown as ``(x1, x2) sqrt(2) / x3``, so
    correct samples lie on the unit circle whatever the source power and phase; the circle
    is drawn over the samples.

    Parameters
    ----------
    samples : mapping of str to array_like, shape (N, 2)
        Retrieved samples per method, normalised as above.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, (axes,) = new_figure(height_in=FIGURE_HEIGHT_IN * 1.4)
    for order, (name, points) in enumerate(samples.items()):
        points = np.asarray(points, dtype=float)
        step = thin(points.shape[0])
        _markers(axes, points[step, 0], points[step, 1], method_color(name, order), name)
    angle = np.linspace(0.0, 2 * np.pi, CIRCLE_POINTS)
    axes.plot(
        np.cos(angle),
        np.sin(angle),
        "-",
        color="black",
        linewidth=1.0,
        zorder=REFERENCE_ZORDER,
        label="correct (unit circle)",
    )
    axes.set_aspect("equal", adjustable="datalim")
    axes.set_xlabel(r"$x_1 \sqrt{2} / x_3$ (dimensionless)")
    axes.set_ylabel(r"$x_2 \sqrt{2} / x_3$ (dimensionless)")
    axes.set_title("Object space: cone section at unit power")
    legend_outside(axes)
    return figure


def plot_retrieved_frequency(true_hz, retrieved_hz: Mapping[str, np.ndarray], center_hz: float):
    """Retrieved against true frequency per method: paper Fig. 4c / 7b.

    Parameters
    ----------
    true_hz : array_like, shape (N,)
        True frequency of each reading (Hz).
    retrieved_hz : mapping of str to array_like, shape (N,)
        Retrieved frequency per method (Hz), the alias nearest the truth.
    center_hz : float
        Origin of both axes (Hz).

    Returns
    -------
    matplotlib.figure.Figure
    """
    truth = (np.asarray(true_hz, dtype=float) - center_hz) / 1e9
    figure, (axes,) = new_figure()
    step = thin(truth.size)
    for order, (name, retrieved) in enumerate(retrieved_hz.items()):
        offset = (np.asarray(retrieved, dtype=float) - center_hz) / 1e9
        _markers(axes, truth[step], offset[step], method_color(name, order), name)
    ends = np.array([truth.min(), truth.max()])
    axes.plot(
        ends,
        ends,
        "-",
        color="black",
        linewidth=0.9,
        zorder=REFERENCE_ZORDER,
        label="ideal (retrieved = true)",
    )
    axes.set_xlabel(f"true {offset_label(center_hz)}")
    axes.set_ylabel("retrieved frequency offset (GHz)")
    axes.set_title(f"Retrieved against true frequency, offsets from {center_hz / 1e12:.6f} THz")
    legend_outside(axes)
    return figure


def _mark_windows(axes, window_edges_hz, center_hz: float) -> None:
    for number, edge in enumerate(np.asarray(window_edges_hz, dtype=float)):
        axes.axvline(
            (edge - center_hz) / 1e9,
            color="0.6",
            linewidth=0.6,
            zorder=1,
            label="window edges" if number == 0 else None,
        )


def _crlb_band(axes, offset, band) -> None:
    """The +-1 sigma Cramer-Rao band over the data: translucent fill and solid edges."""
    axes.fill_between(
        offset,
        -band,
        band,
        color="0.35",
        alpha=REFERENCE_ALPHA,
        linewidth=0,
        zorder=REFERENCE_ZORDER,
        label="CRLB ±1σ",
    )
    for sign in (-1, 1):
        axes.plot(offset, sign * band, "-", color="black", linewidth=0.7, zorder=REFERENCE_ZORDER)


def _error_panels(x, error_hz: Mapping[str, np.ndarray], reference: str):
    """Two panels of frequency error against ``x`` (N,): every method on top, ``reference``
    alone at its own scale below. Returns the figure, the two axes and ``(top unit,
    bottom scale, bottom unit)``."""
    figure, (top, bottom) = new_figure(rows=2, height_in=FIGURE_HEIGHT_IN * 1.6)
    step = thin(x.size)
    scale, unit = frequency_error_unit(np.concatenate([np.ravel(e) for e in error_hz.values()]))
    for number, (name, error) in enumerate(error_hz.items()):
        values = np.asarray(error, dtype=float)[step] / scale
        _markers(top, x[step], values, method_color(name, number), name)
    reference_error = np.asarray(error_hz[reference], dtype=float)
    fine_scale, fine_unit = frequency_error_unit(reference_error)
    color = method_color(reference, list(error_hz).index(reference))
    _markers(bottom, x[step], reference_error[step] / fine_scale, color, reference)
    return figure, (top, bottom), (unit, fine_scale, fine_unit)


def plot_residuals(
    true_hz,
    error_hz: Mapping[str, np.ndarray],
    center_hz: float,
    reference: str,
    crlb_std_hz=None,
    window_edges_hz=None,
):
    """Frequency error against true frequency: paper Fig. 4d / 7c, and Fig. 8 for sets.

    Top: every method. Bottom: ``reference`` alone at its own scale, with the Cramer-Rao
    band ``+-1 sigma`` over it when given.

    Parameters
    ----------
    true_hz : array_like, shape (N,)
        True frequency of each reading (Hz).
    error_hz : mapping of str to array_like, shape (N,)
        Retrieved minus true frequency per method (Hz).
    center_hz : float
        Origin of the frequency axis (Hz).
    reference : str
        Key of ``error_hz`` shown alone in the bottom panel.
    crlb_std_hz : None or array_like, shape (N,)
        Per-reading Cramer-Rao standard deviation (Hz).
    window_edges_hz : None or array_like, shape (K + 1,)
        Edges of the windows of a calibration set (Hz), drawn as vertical lines.

    Returns
    -------
    matplotlib.figure.Figure
    """
    truth = np.asarray(true_hz, dtype=float)
    offset = (truth - center_hz) / 1e9
    order = np.argsort(truth)
    figure, (top, bottom), (unit, fine_scale, fine_unit) = _error_panels(
        offset, error_hz, reference
    )
    if crlb_std_hz is not None:
        _crlb_band(bottom, offset[order], np.asarray(crlb_std_hz, dtype=float)[order] / fine_scale)
    for axes, axes_unit in ((top, unit), (bottom, fine_unit)):
        if window_edges_hz is not None:
            _mark_windows(axes, window_edges_hz, center_hz)
        axes.axhline(0.0, color="black", linewidth=0.6, zorder=1)
        axes.set_ylabel(f"frequency error ({axes_unit})")
        legend_outside(axes)
    top.set_title(
        "Frequency error across the span" if window_edges_hz is not None else "Frequency error"
    )
    bottom.set_xlabel(f"true {offset_label(center_hz)}")
    return figure


def plot_error_histogram(error_hz, crlb_rms_hz: float | None, label: str = "learned"):
    """Histogram of frequency errors with the Cramer-Rao bound drawn over it.

    Parameters
    ----------
    error_hz : array_like, shape (N,)
        Retrieved minus true frequency (Hz).
    crlb_rms_hz : float or None
        RMS over the readings of the per-reading Cramer-Rao standard deviation (Hz); drawn
        as a normal density and as lines at ``+-1 sigma``.
    label : str
        Name of the method.

    Returns
    -------
    matplotlib.figure.Figure
    """
    error = np.asarray(error_hz, dtype=float)
    scale, unit = frequency_error_unit(error)
    figure, (axes,) = new_figure()
    values = error / scale
    rms = float(np.sqrt(np.mean(values**2)))
    axes.hist(
        values,
        bins="auto",
        density=True,
        color=method_color(label, 0),
        alpha=0.55,
        zorder=DATA_ZORDER,
        label=f"{label}, RMS {significant(rms)} {unit}",
    )
    title = f"Error distribution, RMS {significant(rms)} {unit}"
    if crlb_rms_hz is not None:
        sigma = crlb_rms_hz / scale
        grid = np.linspace(min(values.min(), -4 * sigma), max(values.max(), 4 * sigma), 400)
        density = np.exp(-0.5 * (grid / sigma) ** 2) / (sigma * np.sqrt(2 * np.pi))
        axes.plot(
            grid,
            density,
            "-",
            color="black",
            zorder=REFERENCE_ZORDER,
            label=f"CRLB normal, σ {significant(sigma)} {unit}",
        )
        for sign in (-1, 1):
            axes.axvline(
                sign * sigma,
                color="black",
                linestyle="--",
                linewidth=0.8,
                zorder=REFERENCE_ZORDER,
                label="CRLB ±1σ" if sign < 0 else None,
            )
        title += f", RMS / CRLB {significant(rms / sigma)}"
    axes.set_xlabel(f"frequency error ({unit})")
    axes.set_ylabel(f"probability density (1/{unit})")
    axes.set_title(title)
    legend_outside(axes)
    return figure


def plot_error_against_temperature(
    temperature_k,
    error_hz: Mapping[str, np.ndarray],
    reference: str,
    calibrated_range_k,
    crlb_std_hz=None,
):
    """Frequency error against the chip temperature of each reading.

    Top: every method. Bottom: ``reference`` alone at its own scale, with the Cramer-Rao
    ``+-1 sigma`` (RMS over the readings) as a band when given. Both shade the calibrated
    temperature range.

    Parameters
    ----------
    temperature_k : array_like, shape (N,)
        Chip temperature of each reading (K).
    error_hz : mapping of str to array_like, shape (N,)
        Retrieved minus true frequency per method (Hz).
    reference : str
        Key of ``error_hz`` shown alone in the bottom panel (the thermal calibration).
    calibrated_range_k : None or (float, float)
        Lowest and highest calibration temperature (K), shaded where known.
    crlb_std_hz : None or array_like, shape (N,)
        Per-reading Cramer-Rao standard deviation (Hz).

    Returns
    -------
    matplotlib.figure.Figure
    """
    temperature = np.asarray(temperature_k, dtype=float)
    figure, (top, bottom), (unit, fine_scale, fine_unit) = _error_panels(
        temperature, error_hz, reference
    )
    if crlb_std_hz is not None:
        sigma = float(np.sqrt(np.mean(np.asarray(crlb_std_hz, dtype=float) ** 2))) / fine_scale
        bottom.axhspan(
            -sigma,
            sigma,
            color="0.35",
            alpha=REFERENCE_ALPHA,
            linewidth=0,
            zorder=REFERENCE_ZORDER,
            label="CRLB ±1σ (RMS)",
        )
    for axes, axes_unit in ((top, unit), (bottom, fine_unit)):
        if calibrated_range_k is not None:
            low, high = (float(value) for value in calibrated_range_k)
            axes.axvspan(
                low,
                high,
                color="tab:olive",
                alpha=0.12,
                linewidth=0,
                zorder=1,
                label="calibrated temperatures",
            )
        axes.axhline(0.0, color="black", linewidth=0.6, zorder=1)
        axes.set_ylabel(f"frequency error ({axes_unit})")
        legend_outside(axes)
    top.set_title("Frequency error against chip temperature")
    bottom.set_xlabel("chip temperature (K)")
    return figure


def _display_scale(values: np.ndarray, unit: str) -> tuple[float, str]:
    """The SI value of one display unit that suits ``values``, and its name: frequencies
    (``Hz``) as frequency errors are shown, phases (``rad``) in mrad when small."""
    if unit == "Hz":
        return frequency_error_unit(values)
    if unit == "rad" and values.size and float(np.max(np.abs(values))) < MRAD_BELOW_RAD:
        return 1e-3, "mrad"
    return 1.0, unit


def plot_figure_data(data: FigureData):
    """A figure a calibration declares (:class:`FigureData`): its series as lines, markers
    or levels, chosen points ringed, points labelled, a frequency axis as an offset.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, (axes,) = new_figure()
    axes.set_title(data.caption.split(":")[0].split(".")[0])
    if not data.series or all(series.x.size == 0 for series in data.series):
        axes.text(
            0.5, 0.5, data.note, ha="center", va="center", wrap=True, transform=axes.transAxes
        )
        axes.set_axis_off()
        return figure
    every_y = np.concatenate([np.asarray(series.y, dtype=float) for series in data.series])
    y_scale, y_unit = _display_scale(every_y, data.y_unit)
    for index, series in enumerate(data.series):
        x = np.asarray(series.x, dtype=float)
        if data.x_unit == "Hz":
            x = (x - data.x_origin) / 1e9
        y = np.asarray(series.y, dtype=float) / y_scale
        color = method_color(series.label, index)
        if series.style == "level":
            axes.axhline(
                y[0],
                color="black",
                linestyle="--",
                linewidth=0.9,
                zorder=REFERENCE_ZORDER,
                label=series.label,
            )
            continue
        marker = "o" if series.style == "points" else "o-"
        axes.plot(x, y, marker, color=color, zorder=DATA_ZORDER, label=series.label)
        if series.emphasis is not None and np.any(series.emphasis):
            axes.plot(
                x[series.emphasis],
                y[series.emphasis],
                "o",
                markersize=CHOSEN_MARKER_SIZE,
                markerfacecolor="none",
                markeredgecolor="black",
                zorder=REFERENCE_ZORDER,
                label="chosen",
            )
        for at_x, at_y, text in zip(x, y, series.point_labels, strict=False):
            axes.annotate(
                text, (at_x, at_y), textcoords="offset points", xytext=(5, 4), fontsize="small"
            )
    if data.y_unit == "Hz" and every_y.min() > 0 and every_y.max() > 10 * every_y.min():
        axes.set_yscale("log")
    if data.x_unit == "Hz":
        axes.set_xlabel(offset_label(data.x_origin))
    else:
        axes.set_xlabel(f"{data.x_label} ({data.x_unit or 'count'})")
    axes.set_ylabel(f"{data.y_label} ({y_unit})" if y_unit else data.y_label)
    if data.y_unit == "rad":
        axes.axhline(0.0, color="black", linewidth=0.6, zorder=1)
    legend_outside(axes)
    return figure
