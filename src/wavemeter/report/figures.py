"""Figures of a calibration, after the paper's Figs. 4, 7 and 8; pure functions, arrays in.

Each function returns a :class:`matplotlib.figure.Figure` drawn on the Agg canvas, without
pyplot (no global state, no window). Matplotlib is imported only when a figure is made, so
``import wavemeter`` does not import it. Every axis label carries its unit in parentheses;
every axes that shows more than one method has a legend.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = [
    "plot_fringes",
    "plot_object_space",
    "plot_retrieved_frequency",
    "plot_residuals",
    "plot_error_histogram",
    "METHOD_COLORS",
]

#: line colour of each method, so a method looks the same in every figure
METHOD_COLORS = {"learned": "tab:blue", "conventional": "tab:red", "true": "black"}
OTHER_COLORS = ("tab:green", "tab:purple", "tab:orange", "tab:brown")
FIGURE_SIZE_IN = (7.0, 4.2)
MARKER_SIZE = 4.0
MAX_MARKERS = 6000
POWER_UNITS = ((1.0, "W"), (1e-3, "mW"), (1e-6, "uW"), (1e-9, "nW"))


def _new_figure(rows: int = 1, height_in: float = FIGURE_SIZE_IN[1]):
    """A figure with ``rows`` stacked axes sharing x, on an Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(FIGURE_SIZE_IN[0], height_in), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    return figure, axes


def _color(name: str, order: int) -> str:
    return METHOD_COLORS.get(name.split()[0], OTHER_COLORS[order % len(OTHER_COLORS)])


def _thin(count: int) -> slice:
    """Every k-th point so that at most ``MAX_MARKERS`` markers are drawn."""
    return slice(None, None, max(1, -(-count // MAX_MARKERS)))


def _offset_label(center_hz: float) -> str:
    return f"frequency offset from {center_hz / 1e12:.6f} THz (GHz)"


def _power_unit(powers_w: np.ndarray) -> tuple[float, str]:
    """Display scale and unit name for powers in W: the largest unit below the peak."""
    peak = float(np.max(np.abs(powers_w))) if powers_w.size else 1.0
    for scale, name in POWER_UNITS:
        if peak >= scale:
            return scale, name
    return POWER_UNITS[-1]


def _frequency_error_unit(error_hz: np.ndarray) -> tuple[float, str]:
    """MHz for errors below 1 GHz, GHz above."""
    peak = float(np.max(np.abs(error_hz))) if np.size(error_hz) else 0.0
    return (1e9, "GHz") if peak >= 1e9 else (1e6, "MHz")


def plot_fringes(
    frequency_hz,
    powers_w,
    center_hz: float,
    port_names,
    model_frequency_hz=None,
    model_powers_w=None,
    model_label: str = "learned",
):
    """Port readings (markers) and the fitted fringe model (lines): paper Fig. 4b / 7a.

    Parameters
    ----------
    frequency_hz : array_like, shape (N,)
        Frequency of each reading (Hz).
    powers_w : array_like, shape (N, n)
        Port readings (W).
    center_hz : float
        Origin of the frequency axis (Hz).
    port_names : sequence of str, length n
    model_frequency_hz : None or array_like, shape (M,)
        Frequencies (Hz) of the model curve, increasing.
    model_powers_w : None or array_like, shape (M, n)
        Model readings (W) at ``model_frequency_hz``.
    model_label : str
        Name of the method the model belongs to.

    Returns
    -------
    matplotlib.figure.Figure
    """
    frequency = np.asarray(frequency_hz, dtype=float)
    powers = np.asarray(powers_w, dtype=float)
    scale, unit = _power_unit(powers)
    figure, (axes,) = _new_figure()
    thin = _thin(frequency.size)
    for port, name in enumerate(port_names):
        color = f"C{port % 10}"
        axes.plot(
            (frequency[thin] - center_hz) / 1e9,
            powers[thin, port] / scale,
            ".",
            markersize=MARKER_SIZE,
            color=color,
            label=f"{name} measured",
        )
        if model_powers_w is not None:
            axes.plot(
                (np.asarray(model_frequency_hz) - center_hz) / 1e9,
                np.asarray(model_powers_w)[:, port] / scale,
                "-",
                color=color,
                label=f"{name} {model_label} fit",
            )
    axes.set_xlabel(_offset_label(center_hz))
    axes.set_ylabel(f"port power ({unit})")
    axes.set_title("Port fringes and the fitted model")
    axes.legend(fontsize="small", ncols=2)
    return figure


def plot_object_space(true_phase_rad, samples: Mapping[str, np.ndarray]):
    """Object-space samples on the unit-power section of the cone: paper Fig. 4a.

    Each sample ``x = P [cos t, sin t, sqrt 2]`` is shown as ``(x1, x2) sqrt(2) / x3``, so
    the correct samples lie on the unit circle whatever the source power.

    Parameters
    ----------
    true_phase_rad : array_like, shape (N,)
        Phase of each reading from its known frequency (rad): the correct samples.
    samples : mapping of str to array_like, shape (N, 2)
        Retrieved samples per method, normalised as above, in the method's calibrated
        frame (phase zero at its centre frequency).

    Returns
    -------
    matplotlib.figure.Figure
    """
    phase = np.asarray(true_phase_rad, dtype=float)
    figure, (axes,) = _new_figure(height_in=FIGURE_SIZE_IN[0] * 0.8)
    thin = _thin(phase.size)
    axes.plot(np.cos(phase[thin]), np.sin(phase[thin]), ".", color="black", label="correct")
    for order, (name, points) in enumerate(samples.items()):
        points = np.asarray(points, dtype=float)
        axes.plot(
            points[thin, 0],
            points[thin, 1],
            ".",
            markersize=MARKER_SIZE,
            alpha=0.6,
            color=_color(name, order),
            label=name,
        )
    axes.set_aspect("equal", adjustable="datalim")
    axes.set_xlabel("x1 sqrt(2) / x3 (dimensionless)")
    axes.set_ylabel("x2 sqrt(2) / x3 (dimensionless)")
    axes.set_title("Object space: cone section at unit power")
    axes.legend(fontsize="small")
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
    figure, (axes,) = _new_figure()
    thin = _thin(truth.size)
    ends = np.array([truth.min(), truth.max()])
    axes.plot(ends, ends, "-", color="black", linewidth=0.8, label="ideal (retrieved = true)")
    for order, (name, retrieved) in enumerate(retrieved_hz.items()):
        axes.plot(
            truth[thin],
            (np.asarray(retrieved, dtype=float)[thin] - center_hz) / 1e9,
            ".",
            markersize=MARKER_SIZE,
            color=_color(name, order),
            label=name,
        )
    axes.set_xlabel(f"true {_offset_label(center_hz)}")
    axes.set_ylabel(f"retrieved {_offset_label(center_hz)}")
    axes.set_title("Retrieved against true frequency")
    axes.legend(fontsize="small")
    return figure


def _mark_windows(axes, window_edges_hz, center_hz: float) -> None:
    for number, edge in enumerate(np.asarray(window_edges_hz, dtype=float)):
        axes.axvline(
            (edge - center_hz) / 1e9,
            color="0.7",
            linewidth=0.6,
            zorder=0,
            label="window edges" if number == 0 else None,
        )


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
    band ``+-1 sigma`` when given.

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
    figure, (top, bottom) = _new_figure(rows=2, height_in=FIGURE_SIZE_IN[1] * 1.6)
    thin = _thin(truth.size)
    scale, unit = _frequency_error_unit(np.concatenate([np.ravel(e) for e in error_hz.values()]))
    for number, (name, error) in enumerate(error_hz.items()):
        top.plot(
            offset[thin],
            np.asarray(error, dtype=float)[thin] / scale,
            ".",
            markersize=MARKER_SIZE,
            color=_color(name, number),
            label=name,
        )
    reference_error = np.asarray(error_hz[reference], dtype=float)
    fine_scale, fine_unit = _frequency_error_unit(reference_error)
    bottom.plot(
        offset[thin],
        reference_error[thin] / fine_scale,
        ".",
        markersize=MARKER_SIZE,
        color=_color(reference, list(error_hz).index(reference)),
        label=reference,
    )
    if crlb_std_hz is not None:
        band = np.asarray(crlb_std_hz, dtype=float)[order] / fine_scale
        bottom.fill_between(
            offset[order],
            -band,
            band,
            color="0.5",
            alpha=0.35,
            linewidth=0,
            zorder=0,
            label="CRLB +-1 sigma",
        )
    for axes, axes_unit in ((top, unit), (bottom, fine_unit)):
        if window_edges_hz is not None:
            _mark_windows(axes, window_edges_hz, center_hz)
        axes.axhline(0.0, color="black", linewidth=0.6)
        axes.set_ylabel(f"frequency error ({axes_unit})")
        axes.legend(fontsize="small", loc="upper right")
    top.set_title(
        "Frequency error across the span" if window_edges_hz is not None else "Frequency error"
    )
    bottom.set_xlabel(f"true {_offset_label(center_hz)}")
    return figure


def plot_error_histogram(error_hz, crlb_rms_hz: float | None, label: str = "learned"):
    """Histogram of frequency errors with the Cramer-Rao bound marked.

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
    scale, unit = _frequency_error_unit(error)
    figure, (axes,) = _new_figure()
    values = error / scale
    axes.hist(values, bins="auto", density=True, color=_color(label, 0), alpha=0.7, label=label)
    if crlb_rms_hz is not None:
        sigma = crlb_rms_hz / scale
        grid = np.linspace(min(values.min(), -4 * sigma), max(values.max(), 4 * sigma), 400)
        density = np.exp(-0.5 * (grid / sigma) ** 2) / (sigma * np.sqrt(2 * np.pi))
        axes.plot(grid, density, "-", color="black", label=f"CRLB normal, sigma {sigma:.4g} {unit}")
        for sign in (-1, 1):
            axes.axvline(sign * sigma, color="black", linestyle="--", linewidth=0.8)
    axes.set_xlabel(f"frequency error ({unit})")
    axes.set_ylabel(f"probability density (1/{unit})")
    axes.set_title(f"Error distribution, RMS {np.sqrt(np.mean(values**2)):.4g} {unit}")
    axes.legend(fontsize="small")
    return figure
