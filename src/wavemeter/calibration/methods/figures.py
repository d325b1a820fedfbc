"""The figure data the methods declare for their reports: fringes and object samples.

Pure functions of a fitted model and some readings, returning
:class:`~wavemeter.calibration.contract.figures.FringePanel` records and object-space
samples; each calibrator calls the ones that fit its model from ``fringe_panels`` and
``object_samples`` (paper Fig. 4a, 4b and 7a).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from ...model.cone import SQRT2, cone_vectors
from ..contract.figures import FringePanel

__all__ = [
    "FRINGE_HALF_WIDTH_FSR",
    "MODEL_POINTS",
    "band_fringe_panel",
    "fringe_panel",
    "near",
    "pseudo_inverse",
    "unit_power_samples",
]

#: points of a model curve drawn over the readings
MODEL_POINTS = 1000
#: half width, in FSRs, of the stretch of a sweep shown as fringes
FRINGE_HALF_WIDTH_FSR = 1.5


def near(frequency_hz: np.ndarray, anchor_hz: float, fsr_hz: float) -> np.ndarray:
    """The readings within ``FRINGE_HALF_WIDTH_FSR`` of ``anchor_hz``."""
    return np.abs(frequency_hz - anchor_hz) <= FRINGE_HALF_WIDTH_FSR * fsr_hz


def _relative_power(monitor_w, rows) -> np.ndarray | float:
    """The monitored power of some readings relative to its mean (the map is per unit of
    the mean monitor reading), as a column; 1 without a monitor."""
    if monitor_w is None:
        return 1.0
    monitor = monitor_w[rows]
    return (monitor / monitor.mean())[:, None]


def fringe_panel(
    map_w: np.ndarray,
    center_hz: float,
    model_phase_rad,
    frequency_hz: np.ndarray,
    powers_w: np.ndarray,
    *,
    monitor_w=None,
    rows=None,
    noise_std_w=None,
    title: str = "",
) -> FringePanel:
    """Readings of ``rows`` of a sweep, the fringes of one cone map and its fit at each.

    Parameters
    ----------
    map_w : ndarray, shape (n, 3)
        The map (W).
    center_hz : float
        Origin of the frequency axis (Hz).
    model_phase_rad : callable
        ``phase(frequency_hz) -> rad``: the model's phase of a reading drawn at a frequency.
    frequency_hz, powers_w : ndarray
        The sweep's frequencies (Hz) and readings (W) at which the readings are drawn.
    monitor_w : None or ndarray
        Its monitored source power.
    rows : None or ndarray of bool
        The readings to draw (default all).
    noise_std_w : float or None
        Detector noise estimate (W).
    title : str
        What the panel shows.
    """
    rows = np.ones(frequency_hz.size, dtype=bool) if rows is None else rows
    frequency, powers = frequency_hz[rows], powers_w[rows]
    fitted = cone_vectors(model_phase_rad(frequency)) @ map_w.T * _relative_power(monitor_w, rows)
    model_hz = np.linspace(frequency.min(), frequency.max(), MODEL_POINTS)
    return FringePanel(
        center_hz=center_hz,
        frequency_hz=frequency,
        powers_w=powers,
        fitted_w=fitted,
        model_frequency_hz=model_hz,
        model_powers_w=cone_vectors(model_phase_rad(model_hz)) @ map_w.T,
        noise_std_w=noise_std_w,
        title=title,
    )


def band_fringe_panel(
    band_model, frequency_hz, powers_w, *, monitor_w=None, rows=None, noise_std_w=None, title=""
) -> FringePanel:
    """Readings of ``rows``, the fringes of a wide-band model (its phase polynomial and its
    map at each frequency) and its fit at each reading."""
    rows = np.ones(frequency_hz.size, dtype=bool) if rows is None else rows
    frequency, powers = frequency_hz[rows], powers_w[rows]

    def model_powers_w(at_hz):
        vectors = cone_vectors(band_model.phase_rad(at_hz))
        return np.einsum("knc,kc->kn", band_model.maps_at(at_hz), vectors)

    model_hz = np.linspace(frequency.min(), frequency.max(), MODEL_POINTS)
    return FringePanel(
        center_hz=band_model.center_hz,
        frequency_hz=frequency,
        powers_w=powers,
        fitted_w=model_powers_w(frequency) * _relative_power(monitor_w, rows),
        model_frequency_hz=model_hz,
        model_powers_w=model_powers_w(model_hz),
        noise_std_w=noise_std_w,
        title=title,
    )


def unit_power_samples(inverse_maps, readings: np.ndarray, phase_rad: np.ndarray) -> np.ndarray:
    """Retrieved object samples ``r [cos t, sin t]`` (N, 2), ``r = |x_12| sqrt 2 / x_3``
    (on the unit circle for a reading of the model), with ``x = A+ p`` under one map's
    pseudo-inverse (3, n) or each reading's own (N, 3, n)."""
    if inverse_maps.ndim == 2:
        objects = readings @ inverse_maps.T
    else:
        objects = np.einsum("kcn,kn->kc", inverse_maps, readings)
    radius = np.hypot(objects[:, 0], objects[:, 1]) * SQRT2 / objects[:, 2]
    return radius[:, None] * np.column_stack([np.cos(phase_rad), np.sin(phase_rad)])


def pseudo_inverse(map_w: np.ndarray) -> np.ndarray:
    """The Moore-Penrose inverse of a map (n, 3), or of a stack of maps (N, n, 3)."""
    return linalg.pinv(map_w) if map_w.ndim == 2 else np.linalg.pinv(map_w)


class MapSamplesMixin:
    """``object_samples`` of a calibrator with one map ``map_`` and a ``phase``: the
    readings within ``FRINGE_HALF_WIDTH_FSR`` of the centre, at unit source power."""

    def object_samples(self, powers_w, frequency_hz, temperature_k=None):
        rows = near(np.asarray(frequency_hz, dtype=float), self.center_hz_, self.fsr_hz_)
        readings = np.asarray(powers_w, dtype=float)[rows]
        inputs = {}
        if "temperature_k" in self.requires:
            inputs["temperature_k"] = np.broadcast_to(temperature_k, rows.shape)[rows]
        phase = self.phase(readings, **inputs)
        return unit_power_samples(pseudo_inverse(self.map_), readings, phase)
