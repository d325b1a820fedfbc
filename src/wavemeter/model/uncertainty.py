"""Per-reading uncertainty of the retrieved phase and frequency, by the delta method.

To first order in a reading's noise ``e`` and in the error ``dA`` of the calibrated map,
the retrieved phase moves by ``g . e - g . (dA x)``, ``g = d t_hat / d p`` (n,):

* :func:`pinv_phase_gradient`, :func:`ml_phase_gradient`: ``g`` for the pseudo-inverse and
  the maximum-likelihood retrievals (the latter's variance is the Cramer-Rao bound);
* :func:`phase_std_rad`: the reading noise's part, ``sqrt(sum_j g_j^2 sigma_j^2)``;
* :func:`fit_parameter_covariance`: the covariance of the calibration's map and delay;
* :func:`calibration_frequency_variance_hz2`: the calibration's part of a reading's
  frequency variance, which adds to the reading noise's;
* :func:`student_factor`: the inflation ``sqrt(dof / (dof - 2))`` for a noise estimated on
  ``dof`` degrees of freedom.

Theory (the derivations): the docs' uncertainty page (``docs/theory/uncertainty.rst``,
"First order in the noise and the map's error").
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy import linalg

from ..exceptions import InputError, shown
from ..validation import check_positive
from .cone import cone_vectors
from .limits import check_noise_std, stacked_phase_and_power

__all__ = [
    "pinv_phase_gradient",
    "ml_phase_gradient",
    "phase_std_rad",
    "fit_parameter_covariance",
    "calibration_frequency_variance_hz2",
    "calibration_variance_hz2",
    "map_frequency_gradient_hz",
    "student_factor",
]


def _matrix(name: str, value, shape: tuple) -> np.ndarray:
    """A float array whose shape matches ``shape`` (None entries match any size)."""
    array = np.asarray(value, dtype=float)
    if array.ndim != len(shape) or any(
        want is not None and got != want for got, want in zip(array.shape, shape, strict=True)
    ):
        wanted = ", ".join("any" if want is None else str(want) for want in shape)
        raise InputError(f"{name} must have shape ({wanted}), got {array.shape}", parameter=name)
    return array


def _map_or_stack(name: str, value, shape: tuple) -> np.ndarray:
    """One matrix of ``shape``, or a stack of them (one per reading): ``(N, *shape)``."""
    array = np.asarray(value, dtype=float)
    if array.ndim == len(shape) + 1:
        return _matrix(name, array, (None, *shape))
    if array.ndim != len(shape):
        wanted = ", ".join("any" if want is None else str(want) for want in shape)
        raise InputError(
            f"{name} must have shape ({wanted}) or, one per reading, (N, {wanted}), got "
            f"{array.shape}",
            parameter=name,
        )
    return _matrix(name, array, shape)


def _inverse_variance(noise_std_w, ports: int) -> np.ndarray:
    """Weights ``1 / sigma_j^2`` (1/W^2), shape (ports,)."""
    noise = check_noise_std("noise_std_w", noise_std_w, ports)
    return np.broadcast_to(1.0 / np.square(noise), (ports,))


def pinv_phase_gradient(powers, map_pinv) -> np.ndarray:
    """Derivative of the pseudo-inverse phase ``atan2(x_2, x_1)``, ``x = A+ p``, by ``p``.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Port readings (W).
    map_pinv : array_like, shape (3, n) or (N, 3, n)
        Moore-Penrose inverse ``A+`` of the map, or one per reading
        (:func:`wavemeter.model.retrieval.stacked_pinv`).

    Returns
    -------
    ndarray, shape (N, n), rad/W

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.model import phase_std_rad, pinv_phase_gradient
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> gradient = pinv_phase_gradient(powers[:3], np.linalg.pinv(cal.map_))  # rad/W
    >>> gradient.shape
    (3, 3)
    >>> std_hz = phase_std_rad(gradient, 5e-7) * cal.fsr_hz_ / (2 * np.pi)
    >>> print(np.round(std_hz / 1e6, 1))  # MHz: the reading noise's share of each reading
    [14.2 14.2 14.1]
    """
    inverse = _map_or_stack("map_pinv", map_pinv, (3, None))
    readings = _matrix("powers", powers, (None, inverse.shape[-1]))
    if inverse.ndim == 2:
        x_1, x_2 = readings @ inverse[0], readings @ inverse[1]
        radius2 = x_1**2 + x_2**2
        return (x_1[:, None] * inverse[1] - x_2[:, None] * inverse[0]) / radius2[:, None]
    if inverse.shape[0] != readings.shape[0]:
        raise InputError(
            f"map_pinv must hold one inverse per reading: {inverse.shape[0]} for "
            f"{readings.shape[0]} readings",
            parameter="map_pinv",
        )
    first, second = inverse[:, 0], inverse[:, 1]
    x_1 = np.einsum("ij,ij->i", readings, first)
    x_2 = np.einsum("ij,ij->i", readings, second)
    radius2 = x_1**2 + x_2**2
    return (x_1[:, None] * second - x_2[:, None] * first) / radius2[:, None]


def ml_phase_gradient(map_, phase_rad, power, noise_std_w) -> np.ndarray:
    """Derivative of the weighted maximum-likelihood phase by the reading, at its optimum.

    Parameters
    ----------
    map_ : array_like, shape (n, 3) or (N, n, 3)
        The map ``A``, or one map per reading (reading ``k`` uses ``map_[k]``).
    phase_rad : array_like, shape (N,)
        Phase ``t`` of each reading (rad).
    power : float or array_like, shape (N,)
        Source power ``P`` in the unit ``map_`` is scaled by (1 for a fitted map at the
        calibration's power; :func:`wavemeter.model.retrieval.source_power_ratio`).
    noise_std_w : float or array_like, shape (n,)
        Detector noise per port (W); only the ratios between ports matter.

    Returns
    -------
    ndarray, shape (N, n), rad/W
        ``g = W a_perp / (a_perp' W a_perp)``; ``sum_j g_j^2 sigma_j^2`` is the inverse
        Fisher information on ``t``.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.model import ml_phase_gradient, phase_std_rad
    >>> A = wm.Interferometer.ideal(ports=3, fsr_hz=50e9).true_map()
    >>> gradient = ml_phase_gradient(A, np.array([0.0, 1.0]), 1e-3, 5e-7)  # rad/W

    Its standard deviation is the Cramer-Rao bound: 9.75 MHz for an ideal 3x3 meter at
    1 mW with 0.5 uW noise and a 50 GHz FSR:

    >>> print(np.round(phase_std_rad(gradient, 5e-7) * 50e9 / (2 * np.pi) / 1e6, 2))
    [9.75 9.75]
    """
    matrix = _map_or_stack("map_", map_, (None, 3))
    weight = _inverse_variance(noise_std_w, matrix.shape[-2])
    if matrix.ndim == 2:
        t = np.atleast_1d(np.asarray(phase_rad, dtype=float))
        tangent = np.stack([-np.sin(t), np.cos(t), np.zeros_like(t)], axis=-1)
        along_t = tangent @ matrix.T * np.asarray(power, dtype=float)[..., None]
        along_p = cone_vectors(t) @ matrix.T
    else:
        t, power = stacked_phase_and_power(matrix, phase_rad, power)
        tangent = np.stack([-np.sin(t), np.cos(t), np.zeros_like(t)], axis=-1)
        along_t = np.einsum("kji,ki->kj", matrix, tangent) * power[..., None]
        along_p = np.einsum("kji,ki->kj", matrix, cone_vectors(t))
    weighted_p = along_p * weight
    share = np.einsum("ij,ij->i", along_t, weighted_p) / np.einsum("ij,ij->i", along_p, weighted_p)
    perpendicular = along_t - along_p * share[:, None]
    weighted = perpendicular * weight
    return weighted / np.einsum("ij,ij->i", weighted, perpendicular)[:, None]


def phase_std_rad(gradient, noise_std_w) -> np.ndarray:
    """Standard deviation (rad) of a phase with gradient ``g``: ``sqrt(sum_j g_j^2 sigma_j^2)``.

    Parameters
    ----------
    gradient : array_like, shape (N, n)
        ``d t / d p`` of each reading (rad/W).
    noise_std_w : float or array_like, shape (n,)
        Detector noise per port (W).

    Returns
    -------
    ndarray, shape (N,), rad

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.model import phase_std_rad
    >>> gradient = np.array([[1000.0, -500.0, -500.0]])  # rad/W of one reading
    >>> print(phase_std_rad(gradient, 5e-7))  # sqrt(sum g^2 sigma^2), rad
    [0.00061237]
    >>> print(phase_std_rad(gradient, np.array([5e-7, 5e-7, 1e-6])))  # noise per port
    [0.00075]
    """
    g = _matrix("gradient", gradient, (None, None))
    noise = check_noise_std("noise_std_w", noise_std_w, g.shape[1])
    return np.sqrt(np.square(g * noise).sum(axis=1))


def _fisher(x, d, matrix, weight) -> np.ndarray:
    """``J' W J`` of the fit, blockwise (map entries row-major, then the ``q`` nonlinear
    parameters whose object derivatives are ``d``, shape (q, N, k))."""
    ports, k = matrix.shape
    size = ports * k
    count = d.shape[0]
    fisher = np.empty((size + count, size + count))
    fisher[:size, :size] = np.kron(np.diag(weight), x.T @ x)
    for first in range(count):
        cross = (weight[:, None] * (matrix @ (x.T @ d[first]).T)).ravel()
        fisher[:size, size + first] = fisher[size + first, :size] = cross
        for second in range(first, count):
            block = d[first].T @ d[second]
            value = np.einsum("j,jl,lm,jm->", weight, matrix, block, matrix)
            fisher[size + first, size + second] = fisher[size + second, size + first] = value
    return fisher


def _inverse(fisher: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive definite information matrix, Jacobi-scaled first
    (map entries in W and the delay in s differ by many decades)."""
    singular = InputError(
        "the calibration sweep does not determine the map and the nonlinear parameters (its "
        "Fisher matrix is singular): too few readings, or too little of the phase covered",
        parameter="objects",
    )
    diagonal = np.diag(fisher)
    if not np.all(np.isfinite(diagonal) & (diagonal > 0)):
        raise singular
    scale = 1.0 / np.sqrt(diagonal)
    try:
        factor = linalg.cho_factor(fisher * np.outer(scale, scale))
    except linalg.LinAlgError as exc:
        raise singular from exc
    inverse = linalg.cho_solve(factor, np.eye(fisher.shape[0])) * np.outer(scale, scale)
    return 0.5 * (inverse + inverse.T)


def _score_of_directions(x, d, matrix, weight, directions) -> np.ndarray:
    """``J_k' W c_k`` (N, n k + q) of every reading: the parameters' gradient of the
    weighted residual energy along the reading's extra noise direction ``c_k`` (W)."""
    weighted = directions * weight
    samples = x.shape[0]
    along_map = -(weighted[:, :, None] * x[:, None, :]).reshape(samples, -1)
    along_theta = [-np.einsum("ij,ij->i", d_q @ matrix.T, weighted) for d_q in d]
    return np.column_stack([along_map, *along_theta])


def fit_parameter_covariance(
    objects,
    objects_delay_derivative,
    map_,
    noise_std_w,
    *,
    weighted: bool = True,
    noise_directions_w=None,
) -> np.ndarray:
    """Covariance of the least-squares calibration ``[vec(map_) row-major, theta]``.

    ``theta`` are the nonlinear parameters of the object vectors: the delay alone for the
    paper's model, or more (the thermal model's delay, bias rate and delay rate). For the
    noise-weighted fit (the maximum-likelihood one) it is the inverse Fisher matrix
    ``(J' W J)^-1``. The paper's fit is unweighted: its covariance is the sandwich
    ``H^-1 (J' S J) H^-1`` with ``H = J' J`` and ``S = diag(s_j^2)``, which equals the
    inverse Fisher matrix when every port has the same noise. Each map row is its own
    least-squares fit either way; weights move only ``theta``, shared by the ports.

    Parameters
    ----------
    objects : array_like, shape (N, k)
        Object vectors ``X`` of the sweep at the fitted parameters (``k = 3``, or 4 with a
        column of ones for per-port offsets).
    objects_delay_derivative : array_like, shape (N, k) or (q, N, k)
        ``D = dX / d theta``: by the delay alone (1/s), or by each of ``q`` parameters.
    map_ : array_like, shape (n, k)
        Fitted map (W).
    noise_std_w : float or array_like, shape (n,)
        Detector noise per port (W).
    weighted : bool
        Covariance of the noise-weighted fit (default) or of the unweighted one.
    noise_directions_w : None or array_like, shape (N, n)
        Noise of each reading along one direction besides the white detector noise: its
        covariance is ``c_k c_k'`` (W^2), e.g. a phase scatter ``s_k`` (rad) times the
        fringe tangent ``P A u'(t_k)`` for a chip temperature known to ``s_k / rate``. It
        adds ``B^-1 (sum_k J_k' W c_k c_k' W J_k) B^-1`` (``B`` the information matrix of
        the fit: the sandwich).

    Returns
    -------
    ndarray, shape (n k + q, n k + q)
        In the order ``A[0, 0], A[0, 1], ..., A[n-1, k-1], theta``.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.model import cone_vectors, delay_phase_rad, fit_parameter_covariance
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> phase = delay_phase_rad(f_hz, cal.center_hz_, cal.delay_s_)
    >>> X = cone_vectors(phase)  # the object vectors, (200, 3)
    >>> offset_hz = (f_hz - cal.center_hz_)[:, None]
    >>> D = 2 * np.pi * offset_hz * cone_vectors(phase + np.pi / 2)  # dX / dtau
    >>> D[:, 2] = 0.0  # the cone axis does not move
    >>> noise_w = cal.noise_std_w_
    >>> covariance = fit_parameter_covariance(X, D, cal.map_, noise_w, weighted=False)
    >>> covariance.shape  # the 9 map entries and the delay
    (10, 10)

    The delay's standard error, as an FSR's, is the one the fit reports:

    >>> print(f"{np.sqrt(covariance[-1, -1]) * cal.fsr_hz_**2 / 1e6:.1f} MHz")
    4.1 MHz
    >>> print(f"{cal.delay_std_s_ * cal.fsr_hz_**2 / 1e6:.1f} MHz")
    4.1 MHz
    """
    x = _matrix("objects", objects, (None, None))
    d = np.asarray(objects_delay_derivative, dtype=float)
    if d.ndim == 2:
        d = d[None]
    d = _matrix("objects_delay_derivative", d, (None, *x.shape))
    matrix = _matrix("map_", map_, (None, x.shape[1]))
    weight = _inverse_variance(noise_std_w, matrix.shape[0])
    if weighted:
        bread = _inverse(_fisher(x, d, matrix, weight))
        covariance, fit_weight = bread, weight
    else:
        fit_weight = np.ones_like(weight)
        bread = _inverse(_fisher(x, d, matrix, fit_weight))
        covariance = bread @ _fisher(x, d, matrix, 1.0 / weight) @ bread
    if noise_directions_w is not None:
        directions = _matrix("noise_directions_w", noise_directions_w, (x.shape[0], weight.size))
        score = _score_of_directions(x, d, matrix, fit_weight, directions) @ bread
        covariance = covariance + score.T @ score
    return 0.5 * (covariance + covariance.T)


def map_frequency_gradient_hz(gradient, objects_estimate, hz_per_rad) -> np.ndarray:
    """``df / dvec(A)`` (Hz/W, row-major) of each reading's frequency.

    A map error ``dA`` moves the retrieved phase by ``-g . (dA x)``, so
    ``df / dA_jm = -g_j x_m (df / dt)``.

    Parameters
    ----------
    gradient : array_like, shape (N, n)
        ``d t / d p`` of each reading (rad/W).
    objects_estimate : array_like, shape (N, k)
        The reading's object vector: ``P u(t)``, and a 1 for an offset column.
    hz_per_rad : float or array_like, shape (N,)
        ``df / dt`` (Hz/rad), ``1 / (2 pi tau)``.

    Returns
    -------
    ndarray, shape (N, n k), Hz/W
    """
    g = _matrix("gradient", gradient, (None, None))
    samples, ports = g.shape
    x = _matrix("objects_estimate", objects_estimate, (samples, None))
    scale = np.broadcast_to(np.asarray(hz_per_rad, dtype=float), (samples,))
    return -(g[:, :, None] * x[:, None, :]).reshape(samples, ports * x.shape[1]) * scale[:, None]


def calibration_variance_hz2(map_gradient_hz, parameter_gradient_hz, covariance) -> np.ndarray:
    """Variance (Hz^2) of each reading's frequency from the calibration's covariance.

    Parameters
    ----------
    map_gradient_hz : array_like, shape (N, m)
        ``df / dvec(A)`` of each reading (:func:`map_frequency_gradient_hz`).
    parameter_gradient_hz : array_like, shape (N, q)
        ``df / d theta`` of each reading for the ``q`` nonlinear parameters.
    covariance : array_like, shape (m + q, m + q)
        Covariance of ``[vec(A), theta]`` (:func:`fit_parameter_covariance`).

    Returns
    -------
    ndarray, shape (N,), Hz^2
    """
    along_map = _matrix("map_gradient_hz", map_gradient_hz, (None, None))
    along = np.column_stack(
        [
            along_map,
            _matrix("parameter_gradient_hz", parameter_gradient_hz, (along_map.shape[0], None)),
        ]
    )
    c = _matrix("covariance", covariance, (along.shape[1], along.shape[1]))
    return np.einsum("ia,ia->i", along @ c, along)


def calibration_frequency_variance_hz2(
    gradient, objects_estimate, phase_rad, delay_s, covariance
) -> np.ndarray:
    """Variance (Hz^2) of each reading's frequency from the calibration's own uncertainty,
    for the paper's model ``f = f0 + t / (2 pi tau)`` (parameters: map and delay).

    Parameters
    ----------
    gradient : array_like, shape (N, n)
        ``d t / d p`` of each reading (rad/W), e.g. :func:`ml_phase_gradient`.
    objects_estimate : array_like, shape (N, k)
        The reading's object vector: ``P u(t)``, and a 1 for an offset column.
    phase_rad : array_like, shape (N,)
        Retrieved phase (rad, zero at the centre frequency).
    delay_s : float
        Calibrated delay ``tau`` (s).
    covariance : array_like, shape (n k + 1, n k + 1)
        :func:`fit_parameter_covariance` of the calibration.

    Returns
    -------
    ndarray, shape (N,), Hz^2

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.model import cone_vectors, delay_phase_rad, fit_parameter_covariance
    >>> from wavemeter.model import calibration_frequency_variance_hz2, pinv_phase_gradient
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> phase = delay_phase_rad(f_hz, cal.center_hz_, cal.delay_s_)
    >>> X = cone_vectors(phase)  # the object vectors, (200, 3)
    >>> offset_hz = (f_hz - cal.center_hz_)[:, None]
    >>> D = 2 * np.pi * offset_hz * cone_vectors(phase + np.pi / 2)  # dX / dtau
    >>> D[:, 2] = 0.0  # the cone axis does not move
    >>> noise_w = cal.noise_std_w_
    >>> covariance = fit_parameter_covariance(X, D, cal.map_, noise_w, weighted=False)
    >>> covariance.shape  # the 9 map entries and the delay
    (10, 10)
    >>> test = device.powers(f_hz[[50, 150]], power_w=1e-3, noise_w=5e-7, rng=2)
    >>> inverse = np.linalg.pinv(cal.map_)
    >>> gradient = pinv_phase_gradient(test, inverse)
    >>> estimate = test @ inverse.T  # P u(t) of each reading
    >>> variance = calibration_frequency_variance_hz2(
    ...     gradient, estimate, cal.phase(test), cal.delay_s_, covariance
    ... )

    The calibration's share is small beside a reading's own noise (14 MHz): about
    sqrt(3 / N) of it for N = 200 sweep readings:

    >>> print(np.round(np.sqrt(variance) / 1e6, 1))
    [1.7 1.7]
    """
    delay_s = check_positive("delay_s", delay_s)
    to_hz = 1.0 / (2.0 * np.pi * delay_s)
    along_map = map_frequency_gradient_hz(gradient, objects_estimate, to_hz)
    t = _matrix("phase_rad", phase_rad, (along_map.shape[0],))
    return calibration_variance_hz2(along_map, (-t * to_hz / delay_s)[:, None], covariance)


def student_factor(dof) -> float:
    """``sqrt(dof / (dof - 2))``: the standard deviation of a Student t with ``dof`` > 2.

    Inflates a standard deviation whose noise was estimated with ``dof`` degrees of
    freedom, so that ``z = error / std`` has unit variance.

    Examples
    --------
    >>> from wavemeter.model import student_factor
    >>> for dof in (5, 30, 600):  # a noise estimated on few readings widens the stated std
    ...     print(dof, round(student_factor(dof), 3))
    5 1.291
    30 1.035
    600 1.002
    """
    if (
        isinstance(dof, bool)
        or not isinstance(dof, numbers.Real)
        or not (np.isfinite(dof) and dof > 2)
    ):
        raise InputError(f"dof must be a finite number > 2, got {shown(dof)}", parameter="dof")
    return float(np.sqrt(dof / (dof - 2.0)))
