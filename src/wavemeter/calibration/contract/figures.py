"""Figures as data: what a calibration wants drawn in its report, in SI units.

A calibrator describes its figures with these records and ``wavemeter.report`` draws
them; the report knows no calibrator class. :class:`FringePanel` is a stretch of the
sweep with the model's fringes and its fit at each reading (paper Fig. 4b / 7a);
:class:`FigureData` any other figure as labelled series of points and lines.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FigureData", "FringePanel", "Series"]


@dataclass(frozen=True)
class FringePanel:
    """What one fringe panel shows; arrays in SI units.

    Attributes
    ----------
    center_hz : float
        Origin of the frequency axis (Hz).
    frequency_hz : ndarray, shape (N,)
        Frequency of each reading (Hz).
    powers_w : ndarray, shape (N, n)
        Port readings (W).
    fitted_w : ndarray, shape (N, n)
        The model's value at each reading (W).
    model_frequency_hz : ndarray, shape (M,)
        Frequencies of the model curve (Hz).
    model_powers_w : ndarray, shape (M, n)
        The model's fringes there (W).
    noise_std_w : float or None
        Detector noise estimate (W), drawn as a band about zero residual.
    title : str
        What the panel shows (a window, a stage), or empty.
    port_names : tuple of str
        The ports drawn (empty: the calibration's).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> panel = cal.fringe_panels(f_hz, powers)[0]  # what the report's fringe figure draws
    >>> panel.powers_w.shape, panel.model_powers_w.shape
    ((200, 3), (1000, 3))
    >>> residual_w = panel.powers_w - panel.fitted_w

    The residual's RMS is the detector noise of the simulation (0.5 uW):

    >>> print(f"{np.sqrt(np.mean(residual_w**2)) * 1e6:.2f} uW")
    0.47 uW
    """

    center_hz: float
    frequency_hz: np.ndarray
    powers_w: np.ndarray
    fitted_w: np.ndarray
    model_frequency_hz: np.ndarray
    model_powers_w: np.ndarray
    noise_std_w: float | None = None
    title: str = ""
    port_names: tuple = ()


@dataclass(frozen=True)
class Series:
    """One labelled set of points of a figure.

    Attributes
    ----------
    label : str
        Legend text.
    x, y : ndarray, shape (M,)
        Coordinates, in the units of the figure's axes.
    style : {"line", "points", "level"}
        Points joined by a line, markers alone, or a horizontal line at ``y[0]``.
    point_labels : tuple of str
        A text beside each point (empty: none).
    emphasis : None or ndarray of bool, shape (M,)
        Points to ring (e.g. a chosen candidate).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.calibration import Series
    >>> order = np.arange(1, 5)
    >>> rms = Series("held-out error", order, np.array([40e6, 15e6, 14e6, 14e6]), style="points")
    >>> bound = Series("Cramer-Rao bound", order, np.full(4, 13.6e6), style="level")
    >>> rms.label, rms.style, float(bound.y[0] / 1e6)
    ('held-out error', 'points', 13.6)
    """

    label: str
    x: np.ndarray
    y: np.ndarray
    style: str = "line"
    point_labels: tuple = ()
    emphasis: np.ndarray | None = None


@dataclass(frozen=True)
class FigureData:
    """A figure a calibration wants in its report.

    Attributes
    ----------
    name : str
        Its key in the report (``"residual_phase"``).
    caption : str
        What it shows and how to read it.
    x_label, y_label : str
        Axis names, without units.
    x_unit, y_unit : str
        SI units of ``x`` and ``y`` (``"Hz"``, ``"rad"``, ``""``); a frequency axis is
        drawn as an offset from ``x_origin``.
    series : tuple of Series
    x_origin : float
        Origin of a frequency axis (Hz).
    note : str
        A line of text drawn in the figure (e.g. why the orders were chosen).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.calibration import FigureData, Series

    A figure a calibrator asks its report for (``report_figures``): data and labels, drawn
    by the report:

    >>> order = np.arange(1, 5)
    >>> figure = FigureData(
    ...     "cross_validation",
    ...     "Held-out error against the phase order.",
    ...     x_label="phase order",
    ...     y_label="RMS error",
    ...     y_unit="Hz",
    ...     series=(Series("held-out", order, np.array([40e6, 15e6, 14e6, 14e6]), style="points"),),
    ... )
    >>> figure.name, [series.label for series in figure.series]
    ('cross_validation', ['held-out'])
    """

    name: str
    caption: str
    x_label: str
    y_label: str
    x_unit: str = ""
    y_unit: str = ""
    series: tuple = field(default_factory=tuple)
    x_origin: float = 0.0
    note: str = ""
