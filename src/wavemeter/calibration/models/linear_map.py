"""The linear least-squares map of the learned method and its cost, for a trial delay.

For a trial delay ``tau`` the object vectors ``x_k = m_k [cos t_k, sin t_k, sqrt 2]``
(``t_k = 2 pi (f_k - f0) tau``, ``m_k`` the relative monitored power or 1) are known, and
the map minimising ``J = mean ||p_k - A x_k||^2`` is the linear least-squares solution
``A = Ryx Rxx^-1`` (paper Eq. 20-23), computed by an orthogonal factorisation of the
``N x 3`` object matrix rather than by inverting ``Rxx``. Only ``tau`` is nonlinear.

The affine variant appends a column of ones to the object vectors, so the map gains a
fourth column: per-port offsets ``d`` (W) independent of the source power, ``p = A x + d``
(detector dark and ADC offsets). They are separable from the cone axis ``sqrt 2 m_k`` only
when the monitored power ``m_k`` varies over the sweep.

These pure functions serve the learned calibrator, the check of a design FSR against the
sweep (:mod:`wavemeter.calibration.checks.fsr_guard`) and the port diagnostics.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from ...model.cone import cone_vectors, delay_phase_rad

__all__ = [
    "object_vectors",
    "fit_map",
    "map_cost",
    "unfitted_cost",
    "delay_information",
    "object_delay_derivative",
]


def object_vectors(
    frequency_hz, center_hz: float, delay_s: float, scale=None, affine: bool = False
) -> np.ndarray:
    """Object vectors (N, 3), or (N, 4) with a column of ones when ``affine``.

    ``scale`` is the power monitor reading per sample (any linear unit) or None for a
    constant source power.
    """
    phase = delay_phase_rad(frequency_hz, center_hz, delay_s)
    objects = cone_vectors(phase, 1.0 if scale is None else scale)
    if affine:
        objects = np.column_stack([objects, np.ones(objects.shape[0])])
    return objects


def object_delay_derivative(
    frequency_hz, center_hz: float, delay_s: float, scale=None, affine: bool = False
) -> np.ndarray:
    """Derivative ``D = dX / dtau`` (N, 3 or 4) of :func:`object_vectors` in the delay (1/s).

    ``x_k = m_k [cos t_k, sin t_k, sqrt 2]`` with ``t_k = 2 pi (f_k - f0) tau`` gives
    ``dx_k / dtau = 2 pi (f_k - f0) m_k [-sin t_k, cos t_k, 0]``; the offset column is constant.
    """
    offset = np.asarray(frequency_hz, dtype=float) - center_hz
    phase = delay_phase_rad(frequency_hz, center_hz, delay_s)
    power = np.ones_like(offset) if scale is None else np.asarray(scale, dtype=float)
    columns = [-np.sin(phase), np.cos(phase), np.zeros_like(phase)]
    if affine:
        columns.append(np.zeros_like(phase))
    return np.stack(columns, axis=-1) * (2.0 * np.pi * offset * power)[:, None]


def fit_map(objects: np.ndarray, powers: np.ndarray) -> np.ndarray:
    """Least-squares map ``A`` (n, 3) with ``powers ~ objects @ A.T`` (Eq. 23).

    Solved by a rank-revealing QR factorisation of ``objects`` (LAPACK ``gelsy``).
    """
    solution, *_ = linalg.lstsq(objects, powers, lapack_driver="gelsy", check_finite=False)
    return solution.T


def map_cost(objects: np.ndarray, powers: np.ndarray) -> tuple[np.ndarray, float]:
    """Fitted map and its cost ``J = mean_k ||p_k - A x_k||^2`` (Eq. 20), W^2.

    The residual is formed explicitly (not from ``|p|^2 - |Q^T p|^2``) so that ``J`` keeps
    full relative precision down to noiseless data.
    """
    matrix = fit_map(objects, powers)
    residual = powers - objects @ matrix.T
    return matrix, float(np.einsum("ij,ij->", residual, residual) / powers.shape[0])


def unfitted_cost(powers: np.ndarray, scale=None, affine: bool = False) -> float:
    """Cost ``J`` (W^2) of the model with no fringe: readings proportional to the power.

    The least-squares fit keeps only the cone-axis column ``sqrt(2) m_k`` (``m_k`` the
    relative monitored power, or 1), and with ``affine`` the offsets, i.e. the readings
    about their (power-weighted) mean.
    A fit at the true delay removes nearly all of this; a side minimum of ``J`` only a
    little (:func:`wavemeter.calibration.models.delay_search.check_fringes_explained`).
    """
    axis = object_vectors(np.zeros(powers.shape[0]), 0.0, 0.0, scale, affine)[:, 2:]
    return map_cost(axis, powers)[1]


def delay_information(
    frequency_hz, center_hz: float, delay_s: float, map_: np.ndarray, scale=None
) -> float:
    """Gauss-Newton curvature ``G`` of the summed squared residual in the delay, map profiled
    out: ``var(tau) = s^2 / G`` for white noise of variance ``s^2`` per reading (theory: the
    docs' uncertainty page, ``docs/theory/uncertainty.rst``, "The delay's standard error").

    Parameters
    ----------
    frequency_hz : ndarray, shape (N,)
        Calibration frequencies (Hz).
    center_hz : float
        Phase origin (Hz).
    delay_s : float
        Delay at the minimum of ``J`` (s).
    map_ : ndarray, shape (n, 3) or (n, 4)
        Fitted map at that delay (W); a fourth column (offsets) makes the model affine.
    scale : None or ndarray, shape (N,)
        Relative monitored power per reading.

    Returns
    -------
    float
        ``G`` in W^2 / s^2.
    """
    matrix = np.asarray(map_, dtype=float)
    affine = matrix.shape[1] == 4
    objects = object_vectors(frequency_hz, center_hz, delay_s, scale, affine)
    derivative = object_delay_derivative(frequency_hz, center_hz, delay_s, scale, affine)
    image = derivative @ matrix.T
    basis, _ = linalg.qr(objects, mode="economic", check_finite=False)
    off_model = image - basis @ (basis.T @ image)
    return float(np.einsum("ij,ij->", off_model, off_model))
