"""The fringe phase of the wide-band model: what its delay, dispersion and FSR are.

The readings tell the model phase ``t`` from the map only weakly (a rotation of the map
about the cone axis is a change of phase); they do tell each port's fringe phase ``t +
arg z_k``, ``z_k = A_k0 - i A_k1``. This module owns the *fringe phase* ``psi = t + sum_k
w_k arg z_k`` (weights ``w_k`` the ports' fringe power at the centre): its Taylor
coefficients at ``y = 0`` (:func:`fringe_phase_coefficients`), their gradient by every
fitted number for the delta method (:func:`fringe_phase_jacobian`) and the local FSR ``2 pi
/ (dpsi / df)`` (:func:`fringe_slope_rad_per_hz`). Theory: the docs' wide-band page
(``docs/theory/wideband.rst``, "What the phase coefficients are").
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from .wideband_fit import BandModel, band_phase_slope, padded

__all__ = ["fringe_phase_coefficients", "fringe_phase_jacobian", "fringe_slope_rad_per_hz"]


def _fringe_amplitudes(map_coefficients_w: np.ndarray) -> np.ndarray:
    """Legendre coefficients (J + 1, n) of the complex fringe amplitudes ``z_k = A_k0 - i
    A_k1`` (W)."""
    return map_coefficients_w[:, :, 0] - 1j * map_coefficients_w[:, :, 1]


def _weights(amplitudes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``z_k(0)`` (n,) and the weights ``w_k = |z_k(0)|^2 / sum |z_j(0)|^2`` (n,)."""
    centre = legendre.legval(0.0, amplitudes)
    power = np.abs(centre) ** 2
    return centre, power / power.sum()


def _power_series(amplitudes: np.ndarray, order: int) -> np.ndarray:
    """Power-series coefficients ``a_m`` (order + 1, n) of the amplitudes in ``y``."""
    series = np.zeros((order + 1, amplitudes.shape[1]), dtype=complex)
    for port in range(amplitudes.shape[1]):
        power = legendre.leg2poly(amplitudes[:, port])[: order + 1]
        series[: power.size, port] = power
    return series


def _log_series(series: np.ndarray) -> np.ndarray:
    """Coefficients ``l_m`` (m = 0..M) of ``log z(y)`` from those of ``z`` (M + 1, n), by
    ``m a_0 l_m = m a_m - sum_{j<m} j l_j a_{m-j}`` (``l_0`` left 0: only the derivatives
    are used)."""
    logs = np.zeros_like(series)
    for m in range(1, series.shape[0]):
        inner = sum(j * logs[j] * series[m - j] for j in range(1, m))
        logs[m] = (series[m] - inner / m) / series[0]
    return logs


def _reciprocal_series(series: np.ndarray) -> np.ndarray:
    """Coefficients (M + 1, n) of ``1 / z(y)``: ``dl_i / da_m`` is its coefficient
    ``i - m``."""
    inverse = np.zeros_like(series)
    inverse[0] = 1.0 / series[0]
    for m in range(1, series.shape[0]):
        inverse[m] = -sum(series[j] * inverse[m - j] for j in range(1, m + 1)) / series[0]
    return inverse


def fringe_phase_coefficients(model: BandModel, order: int) -> np.ndarray:
    """Taylor coefficients ``psi_i`` (rad) of the fringe phase in ``y`` at the centre.

    ``psi(y) = sum_i psi_i y^i`` near ``y = 0`` (module docstring): ``psi_i = b_i +
    sum_k w_k Im l_k,i`` with ``l_k,i`` the coefficients of ``log z_k(y)``.

    Parameters
    ----------
    model : BandModel
    order : int
        Coefficients wanted, ``1..order``.

    Returns
    -------
    ndarray, shape (order,), rad
    """
    amplitudes = _fringe_amplitudes(model.map_coefficients_w)
    _, weights = _weights(amplitudes)
    logs = _log_series(_power_series(amplitudes, order))
    return padded(model.phase_coefficients_rad, order) + logs[1:].imag @ weights


def fringe_phase_jacobian(model: BandModel, order: int, affine: bool) -> np.ndarray:
    """Gradient of :func:`fringe_phase_coefficients` by every fitted number.

    The numbers in the order of the wide-band calibration's ``parameter_covariance_``:
    the map coefficients row-major over the ports (``3 (J + 1)`` design columns each, plus
    the offset when ``affine``), then the phase coefficients ``b_1..b_P``. ``log z_k`` is
    holomorphic in the power-series coefficients ``a_k,m``, ``dl_k,i / da_k,m = r_k,i-m``
    (``r_k`` those of ``1 / z_k``); the weights move with ``|z_k(0)|^2``.

    Parameters
    ----------
    model : BandModel
    order : int
        Coefficients ``psi_1..psi_order``.
    affine : bool
        The covariance holds an offset per port.

    Returns
    -------
    ndarray, shape (order, n (3 (J + 1) + affine) + P)
    """
    coefficients = model.map_coefficients_w
    blocks, ports = coefficients.shape[0], coefficients.shape[1]
    amplitudes = _fringe_amplitudes(coefficients)
    centre, weights = _weights(amplitudes)
    series = _power_series(amplitudes, order)
    fringe = _log_series(series)[1:].imag  # (order, n)
    mean = fringe @ weights
    inverse = _reciprocal_series(series)
    # power-series coefficient m of Legendre coefficient j: column j of leg2poly
    to_power = np.zeros((order + 1, blocks))
    for j in range(blocks):
        power = legendre.leg2poly(np.eye(blocks)[j])[: order + 1]
        to_power[: power.size, j] = power
    at_centre = legendre.legval(0.0, np.eye(blocks))  # L_j(0)
    total = centre.real**2 + centre.imag**2
    columns = 3 * blocks + (1 if affine else 0)
    gradient = np.zeros((order, ports * columns + model.phase_coefficients_rad.size))
    for port in range(ports):
        # dl_i / dg_j, g_j the complex Legendre coefficient A_j0 - i A_j1
        by_power = np.zeros((order, order + 1), dtype=complex)
        for i in range(1, order + 1):
            by_power[i - 1, : i + 1] = inverse[i::-1, port]
        by_legendre = by_power @ to_power  # (order, J + 1)
        share = (fringe[:, port] - mean) / total.sum()
        weight = weights[port]
        real = weight * by_legendre.imag + np.outer(share, 2.0 * centre[port].real * at_centre)
        imaginary = -weight * by_legendre.real - np.outer(
            share, 2.0 * centre[port].imag * at_centre
        )
        start = port * columns
        gradient[:, start : start + 3 * blocks : 3] = real
        gradient[:, start + 1 : start + 3 * blocks : 3] = imaginary
    phase = model.phase_coefficients_rad.size
    gradient[:, ports * columns :] = np.eye(order, phase)
    return gradient


def fringe_slope_rad_per_hz(model: BandModel, frequency_hz) -> np.ndarray:
    """``dpsi / df`` (rad/Hz) at frequencies (Hz): ``2 pi`` times the fringe's local group
    delay (the weights those at the centre); ``2 pi`` over it is the local FSR."""
    y = model.normalized(frequency_hz)
    amplitudes = _fringe_amplitudes(model.map_coefficients_w)
    _, weights = _weights(amplitudes)
    values = legendre.legval(y, amplitudes, tensor=True)  # (n, N)
    slopes = legendre.legval(y, legendre.legder(amplitudes), tensor=True)
    rotation = np.imag(slopes / values).T @ weights
    return (band_phase_slope(y, model.phase_coefficients_rad) + rotation) / model.half_span_hz
