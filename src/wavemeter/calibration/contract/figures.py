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
