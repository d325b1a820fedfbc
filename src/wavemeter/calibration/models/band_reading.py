"""What a fitted wide-band model says of each reading: its phase, uncertainty and bound.

Every reading has its own map ``A(f)``
(:class:`~wavemeter.calibration.models.wideband_fit.BandModel`), so the single-map
formulas of :mod:`wavemeter.model` are applied with a stack of maps:

* the phase by the pseudo-inverse or the cone maximum likelihood under each reading's map;
* the frequency variance by the delta method (:mod:`wavemeter.model.uncertainty`): the
  reading noise through the retrieval's gradient, ``df / dt = 1 / (dt / df)`` at the
  reading's frequency, plus the calibration's own covariance along
  ``df / dA_j = -(g (x) L_j(y) x) df/dt`` and ``df / db_i = -y^i df/dt``;
* the Cramer-Rao bound under each reading's map and the port noise;
* the cone distance the flags' off-model test compares with its threshold
  (:mod:`~wavemeter.calibration.contract.off_model`);
* the residual phase of the sweep per FSR window, for the diagnostics.

:class:`~wavemeter.calibration.methods.wideband.WidebandCalibrator` answers with these functions.
"""

from __future__ import annotations

import numpy as np

from ...model.cone import cone_vectors
from ...model.limits import crlb_frequency_std
from ...model.retrieval import cone_ml_phase_rad, pinv_phase_rad, source_power_ratio, stacked_pinv
from ...model.uncertainty import (
    calibration_variance_hz2,
    map_frequency_gradient_hz,
    ml_phase_gradient,
    phase_std_rad,
    pinv_phase_gradient,
)
from .wideband_fit import BandModel, band_objects
from .wideband_orders import fsr_windows

__all__ = [
    "band_crlb_hz",
    "band_frequency_variance_hz2",
    "band_off_model",
    "band_phase_gradient",
    "band_phase_rad",
    "residual_phase_by_window",
]


def band_phase_rad(readings, maps, retrieval: str, noise_std_w) -> np.ndarray:
    """Phase (rad) of each reading (N, n) under its own map (N, n, 3): the pseudo-inverse's
    (``retrieval="pinv"``) or the cone maximum likelihood weighted by ``noise_std_w``."""
    if retrieval == "ml":
        return cone_ml_phase_rad(readings, maps, noise_std_w=noise_std_w)
    return pinv_phase_rad(readings, stacked_pinv(maps))


def band_phase_gradient(readings, maps, phase_rad, retrieval: str, noise_std_w) -> np.ndarray:
    """``dt / dp`` (N, n) (rad/W) of the retrieval used, under each reading's map."""
    if retrieval == "ml":
        power = source_power_ratio(readings, maps, phase_rad, noise_std_w)
        return ml_phase_gradient(maps, phase_rad, power, noise_std_w)
    return pinv_phase_gradient(readings, stacked_pinv(maps))


def band_frequency_variance_hz2(
    model: BandModel,
    readings,
    frequency_hz,
    phase_rad,
    maps,
    *,
    retrieval: str,
    noise_std_w,
    covariance=None,
    affine: bool = False,
) -> np.ndarray:
    """Variance (Hz^2) of each reading's frequency, by the delta method (module docstring).

    Parameters
    ----------
    model : BandModel
    readings : ndarray, shape (N, n)
        Offset-corrected readings (W).
    frequency_hz, phase_rad : ndarray, shape (N,)
        The frequency read (Hz) and the phase retrieved (rad).
    maps : ndarray, shape (N, n, 3)
        The map of each reading (W).
    retrieval : {"pinv", "ml"}
    noise_std_w : ndarray, shape (n,)
        Detector noise per port (W).
    covariance : None or ndarray
        Covariance of the map coefficients (and offsets, with ``affine``) and the phase
        coefficients; None: the reading noise alone.
    affine : bool
        The covariance holds a column of offsets per port.

    Returns
    -------
    ndarray, shape (N,), Hz^2
    """
    gradient = band_phase_gradient(readings, maps, phase_rad, retrieval, noise_std_w)
    per_rad = 1.0 / model.phase_slope_rad_per_hz(frequency_hz)
    variance = (phase_std_rad(gradient, noise_std_w) * per_rad) ** 2
    if covariance is None:
        return variance
    power = source_power_ratio(readings, maps, phase_rad, noise_std_w)
    y = model.normalized(frequency_hz)
    map_order = model.map_coefficients_w.shape[0] - 1
    objects = band_objects(y, phase_rad, power, map_order, affine)
    orders = np.arange(1, model.phase_coefficients_rad.size + 1)
    along_phase = -np.power.outer(y, orders) * per_rad[:, None]
    return variance + calibration_variance_hz2(
        map_frequency_gradient_hz(gradient, objects, per_rad), along_phase, covariance
    )


def band_crlb_hz(model: BandModel, readings, frequency_hz, phase_rad, noise_std_w) -> np.ndarray:
    """Cramer-Rao bound (Hz) of each reading at ``frequency_hz`` and ``phase_rad`` under the
    map there and the port noise, its source power free."""
    maps = model.maps_at(frequency_hz)
    power = source_power_ratio(readings, maps, phase_rad, noise_std_w)
    bound = crlb_frequency_std(maps, phase_rad, power, noise_std_w, 2.0 * np.pi)
    return bound / model.phase_slope_rad_per_hz(frequency_hz)


def band_cone_distance(readings, maps, noise_std_w) -> np.ndarray:
    """Each reading's weighted squared distance ``sum_j r_j^2 / s_j^2`` to its map's cone
    (maximum-likelihood phase and power; ``n - 2`` degrees of freedom under the model)."""
    phase = cone_ml_phase_rad(readings, maps, noise_std_w=noise_std_w)
    power = source_power_ratio(readings, maps, phase, noise_std_w)
    image = np.einsum("knc,kc->kn", maps, cone_vectors(phase, power))
    residual = (readings - image) / noise_std_w
    return np.einsum("ij,ij->i", residual, residual)


def band_off_model(readings, maps, noise_std_w, threshold: float) -> np.ndarray:
    """Whether each reading's weighted squared distance to its map's cone exceeds
    ``threshold`` (``OFF_MODEL``: the calibration's
    :class:`~wavemeter.calibration.contract.off_model.OffModelMixin` threshold)."""
    return band_cone_distance(readings, maps, noise_std_w) > threshold


def residual_phase_by_window(frequency_hz, residual_rad, low_hz: float, fsr_hz: float) -> list:
    """Mean and RMS of a residual phase (rad) per FSR window, JSON-ready:
    ``[{"center_hz", "readings", "mean_rad", "rms_rad"}, ...]`` from low to high."""
    windows = fsr_windows(frequency_hz, low_hz, fsr_hz)
    rows = []
    for window in np.unique(windows):
        members = windows == window
        values = residual_rad[members]
        rows.append(
            {
                "center_hz": float(frequency_hz[members].mean()),
                "readings": int(members.sum()),
                "mean_rad": float(values.mean()),
                "rms_rad": float(np.sqrt(np.mean(values**2))),
            }
        )
    return rows
