"""Cone-constrained, noise-weighted maximum-likelihood phase retrieval: the global optimum.

:func:`cone_ml_phase_rad` retrieves each reading's phase as the point of the calibrated
cone nearest the reading in the noise-weighted norm, and :func:`source_power_ratio` its
source power. The optimum is found exactly, not by a local search: the distance to the
cone becomes a secular equation in one Lagrange multiplier, with exactly one root on the
interval that gives the global minimum, found by bracketed Newton steps to ``TOLERANCE``.
It reaches the Cramer-Rao bound where the pseudo-inverse (:func:`pinv_phase_rad`) does
not (an ill-conditioned map, unequal port noise).

Every function also takes a stack of maps, one per reading (``map_`` of shape
``(N, n, 3)``, for a map that changes with frequency; for the pseudo-inverse phase a stack
of inverses from :func:`stacked_pinv`), batched over the stack.

Theory (the problem, the proof of the global optimum, the properties): the docs' page on
maximum-likelihood retrieval (``docs/theory/ml-retrieval.rst``).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from ..exceptions import InputError
from .cone import cone_vectors, wrap_phase_rad
from .limits import check_noise_std

__all__ = [
    "cone_ml_phase_rad",
    "source_power_ratio",
    "pinv_phase_rad",
    "stacked_pinv",
    "cone_frame",
    "noise_weighted_map",
    "TOLERANCE",
    "MAX_STEPS",
]

#: a reading stops once its step changes every coordinate ``z_i`` by less than this, relative
TOLERANCE = 1e-13
#: most steps any reading takes (bisection alone needs about 60 for the worst bracket)
MAX_STEPS = 100

_CONE = np.diag([1.0, 1.0, -0.5])


def _rows_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _check_inputs(powers, map_) -> tuple[np.ndarray, np.ndarray]:
    """Readings (N, n) and the map (n, 3), or a stack of maps (N, n, 3) whose length is N."""
    readings = np.asarray(powers, dtype=float)
    matrix = np.asarray(map_, dtype=float)
    if matrix.ndim not in (2, 3) or matrix.shape[-1] != 3:
        raise InputError(
            f"map_ must have shape (n, 3) or, one map per reading, (N, n, 3), got {matrix.shape}",
            parameter="map_",
        )
    ports = matrix.shape[-2]
    if readings.ndim != 2 or readings.shape[1] != ports:
        raise InputError(
            f"powers must have shape (N, {ports}) for a map of {ports} ports, got {readings.shape}",
            parameter="powers",
        )
    if matrix.ndim == 3:
        if matrix.shape[0] != readings.shape[0]:
            raise InputError(
                f"map_ must hold one map per reading: {matrix.shape[0]} maps for "
                f"{readings.shape[0]} readings",
                parameter="map_",
            )
        if not np.all(np.isfinite(matrix)):
            raise InputError("map_ contains NaN or inf", parameter="map_")
    return readings, matrix


def _check_pinv_inputs(powers, map_pinv) -> tuple[np.ndarray, np.ndarray]:
    """Readings (N, n) and ``A+`` (3, n), or a stack of them (N, 3, n) whose length is N."""
    readings = np.asarray(powers, dtype=float)
    inverse = np.asarray(map_pinv, dtype=float)
    if inverse.ndim not in (2, 3) or inverse.shape[-2] != 3:
        raise InputError(
            f"map_pinv must have shape (3, n) or, one per reading, (N, 3, n), got {inverse.shape}",
            parameter="map_pinv",
        )
    ports = inverse.shape[-1]
    if readings.ndim != 2 or readings.shape[1] != ports:
        raise InputError(
            f"powers must have shape (N, {ports}) for a map of {ports} ports, got {readings.shape}",
            parameter="powers",
        )
    if inverse.ndim == 3 and inverse.shape[0] != readings.shape[0]:
        raise InputError(
            f"map_pinv must hold one inverse per reading: {inverse.shape[0]} for "
            f"{readings.shape[0]} readings",
            parameter="map_pinv",
        )
    return readings, inverse


def _check_stacked_phase(phase_rad, samples: int) -> np.ndarray:
    """Phases (N,) of readings retrieved with a stack of N maps."""
    t = np.asarray(phase_rad, dtype=float)
    if t.shape != (samples,):
        raise InputError(
            f"phase_rad must have shape ({samples},), one per map of the stack, got {t.shape}",
            parameter="phase_rad",
        )
    return t


def noise_weighted_map(matrix: np.ndarray, noise_std_w) -> np.ndarray:
    """``W A`` (n, 3) or (N, n, 3); equal weights (None or one noise for all ports) leave
    ``A`` as is."""
    if noise_std_w is None:
        return matrix
    noise = check_noise_std("noise_std_w", noise_std_w, matrix.shape[-2])
    return matrix if np.ndim(noise) == 0 else matrix / noise[:, None] ** 2


def cone_frame(matrix: np.ndarray, weighted: np.ndarray):
    """Eigenvalues ``k`` of ``Q`` (scaled to max |k| = 1), readings -> ``y``, ``z`` -> objects.

    The eigenvectors ``w`` of ``Q = L^-1 J L^-T`` map back to objects as ``v = L^-T w``: the
    solutions of ``J v = k M v`` with ``v' M v = 1``, which the generalised symmetric
    eigenproblem gives directly. Returns ``(k, to_frame, to_objects)`` with
    ``y = p @ to_frame`` (n, 3) and ``x = (y / (1 + lambda k)) @ to_objects`` (3, 3).
    """
    try:
        kappa, to_objects = linalg.eigh(_CONE, matrix.T @ weighted)
    except linalg.LinAlgError as exc:
        raise InputError(
            "map_ must have rank 3 (three independent columns) for the maximum-likelihood phase",
            parameter="map_",
        ) from exc
    return kappa / np.abs(kappa).max(), weighted @ to_objects, to_objects.T


def _lower_triangular_inverse(factor: np.ndarray) -> np.ndarray:
    """Inverses (N, 3, 3) of lower-triangular 3 x 3 matrices: forward substitution written
    out, several times faster than ``np.linalg.inv`` on the stack."""
    diagonal = 1.0 / np.diagonal(factor, axis1=1, axis2=2)
    inverse = np.zeros_like(factor)
    inverse[:, [0, 1, 2], [0, 1, 2]] = diagonal
    inverse[:, 1, 0] = -factor[:, 1, 0] * diagonal[:, 0] * diagonal[:, 1]
    inverse[:, 2, 1] = -factor[:, 2, 1] * diagonal[:, 1] * diagonal[:, 2]
    inverse[:, 2, 0] = (
        -(factor[:, 2, 0] * diagonal[:, 0] + factor[:, 2, 1] * inverse[:, 1, 0]) * diagonal[:, 2]
    )
    return inverse


def _stacked_cone_frame(matrix: np.ndarray, weighted: np.ndarray):
    """:func:`cone_frame` of every map of a stack (N, n, 3).

    For the map ``A_r`` of reading ``r``: ``M_r = A_r' W A_r = L_r L_r'`` (Cholesky),
    ``Q_r = L_r^-1 J L_r^-T = V_r diag(k_r) V_r'`` (batched symmetric eigenproblem) and
    objects ``L_r^-T V_r``: the same solutions of ``J v = k M v`` with ``v' M v = 1`` as
    the single map's generalised eigenproblem. Returns ``(k, to_frame, to_objects)``:
    ``k`` (3, N), each column ascending and scaled to max |k| = 1; ``y_r = p_r @
    to_frame[r]`` (N, n, 3); ``x_r = (y_r / (1 + lambda_r k_r)) @ to_objects[r]`` (N, 3, 3).
    """
    normal = np.matmul(matrix.transpose(0, 2, 1), weighted)
    try:
        factor = np.linalg.cholesky(normal)
    except np.linalg.LinAlgError as exc:
        raise InputError(
            "every map of map_ must have rank 3 (three independent columns) for the "
            "maximum-likelihood phase",
            parameter="map_",
        ) from exc
    inverse = _lower_triangular_inverse(factor)
    quadric = np.matmul(inverse * np.diagonal(_CONE), inverse.transpose(0, 2, 1))
    kappa, eigenvectors = np.linalg.eigh(quadric)
    to_objects = np.matmul(inverse.transpose(0, 2, 1), eigenvectors)
    kappa = kappa / np.abs(kappa).max(axis=1, keepdims=True)
    return kappa.T, np.matmul(weighted, to_objects), to_objects.transpose(0, 2, 1)


def _secular_root(frame: np.ndarray, kappa: np.ndarray) -> np.ndarray:
    """The root ``lambda`` (N,) of ``sum_i k_i y_i^2 / (1 + lambda k_i)^2`` in its bracket.

    ``frame`` holds ``y`` (N, 3); ``kappa`` is ascending: one negative, two positive values,
    shape (3,) for one map shared by every reading or (3, N) for one map per reading.
    """
    samples = frame.shape[0]
    kappa_col = kappa[:, None] if kappa.ndim == 1 else kappa
    per_reading = kappa_col.shape[1] != 1
    weights = kappa_col * np.square(frame.T)  # k_i y_i^2, shape (3, N): sums run over rows
    root = np.zeros(samples)
    lo = np.broadcast_to(-1.0 / kappa_col[2], (samples,)).copy()
    hi = np.broadcast_to(-1.0 / kappa_col[0], (samples,)).copy()
    last_step = hi - lo
    active = np.arange(samples)
    for _ in range(MAX_STEPS):
        if active.size == 0:
            break
        x = root[active]
        k = kappa_col[:, active] if per_reading else kappa_col
        scale = 1.0 + k * x
        term = weights[:, active] / scale**2
        value = term.sum(axis=0)
        slope = -2.0 * (term * k / scale).sum(axis=0)
        a = np.where(value >= 0, x, lo[active])
        b = np.where(value <= 0, x, hi[active])
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = x - value / slope
        inside = (newton >= a) & (newton <= b) & (np.abs(newton - x) <= 0.5 * last_step[active])
        step = np.where(inside, newton, 0.5 * (a + b)) - x
        root[active], lo[active], hi[active], last_step[active] = x + step, a, b, np.abs(step)
        # relative change of every z_i = y_i / (1 + lambda k_i)
        moved = np.abs(step) * (np.abs(k) / np.abs(scale)).max(axis=0)
        active = active[moved > TOLERANCE]
    return root


def cone_ml_phase_rad(
    powers,
    map_: np.ndarray,
    *,
    noise_std_w=None,
) -> np.ndarray:
    """Maximum-likelihood phase (rad) of readings constrained to the image of the cone.

    The global optimum of the noise-weighted likelihood with the source power free (see
    the module docstring): exact, so it needs no start, no grid of candidate phases and no
    count of steps.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Port readings (W), offsets already removed.
    map_ : ndarray, shape (n, 3) or (N, n, 3)
        The map ``A``, of rank 3; or one map per reading (reading ``k`` uses ``map_[k]``).
    noise_std_w : None, float or array_like, shape (n,)
        Detector noise per port (W); None or one number weighs every port equally.

    Returns
    -------
    ndarray, shape (N,), rad, wrapped to [-pi, pi)

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.model import cone_ml_phase_rad
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.center_hz + np.linspace(-20e9, 20e9, 500)
    >>> noise_w = np.array([2e-7, 2e-7, 2e-6])  # the third port ten times noisier
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=noise_w, rng=1)
    >>> A = device.true_map()  # W per W of source power
    >>> true = wm.wrap_phase_rad(device.phase_rad(f_hz))
    >>> ml = cone_ml_phase_rad(powers, A, noise_std_w=noise_w)
    >>> pinv = wm.retrieve_phase_rad(powers, np.linalg.pinv(A))

    Weighting the ports by their noise reaches the Cramer-Rao bound (a ratio of 1 within
    the scatter of 500 readings); the pseudo-inverse, which weights them equally, does not:

    >>> bound_rad = wm.crlb_frequency_std(A, true, 1e-3, noise_w, 1.0) * 2 * np.pi
    >>> for name, phase in (("ml", ml), ("pinv", pinv)):
    ...     ratio = np.std(wm.wrap_phase_rad(phase - true)) / np.sqrt(np.mean(bound_rad**2))
    ...     print(f"{name}: {ratio:.1f} times the bound")
    ml: 1.0 times the bound
    pinv: 2.1 times the bound
    """
    readings, matrix = _check_inputs(powers, map_)
    if matrix.ndim == 2:
        kappa, to_frame, to_objects = cone_frame(matrix, noise_weighted_map(matrix, noise_std_w))
        frame = readings @ to_frame
        root = _secular_root(frame, kappa)
        objects = (frame / (1.0 + root[:, None] * kappa)) @ to_objects
    else:
        kappa, to_frame, to_objects = _stacked_cone_frame(
            matrix, noise_weighted_map(matrix, noise_std_w)
        )
        frame = np.einsum("kj,kji->ki", readings, to_frame)
        root = _secular_root(frame, kappa)
        objects = np.einsum("ki,kij->kj", frame / (1.0 + root[:, None] * kappa.T), to_objects)
    sign = np.where(objects[:, 2] < 0, -1.0, 1.0)
    return wrap_phase_rad(np.arctan2(sign * objects[:, 1], sign * objects[:, 0]))


def source_power_ratio(powers, map_: np.ndarray, phase_rad, noise_std_w=None) -> np.ndarray:
    """Weighted least-squares source power of each reading relative to the map's (unitless).

    ``P = (u . A' W p) / (u' A' W A u)`` at the given phase: 1 for a reading at the power
    the map was learned at (with a power monitor, at the mean monitored power).

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Port readings (W).
    map_ : ndarray, shape (n, 3) or (N, n, 3)
        The map ``A``, or one map per reading.
    phase_rad : array_like, shape (N,)
        Phase of each reading (rad).
    noise_std_w : None, float or array_like, shape (n,)
        Detector noise per port (W); None or one number weighs every port equally.

    Returns
    -------
    ndarray, shape (N,)

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.model import source_power_ratio
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> dimmer = device.powers(f_hz[:3], power_w=0.5e-3, noise_w=5e-7, rng=2)  # half the power
    >>> ratio = source_power_ratio(dimmer, cal.map_, cal.phase(dimmer))
    >>> print(np.round(ratio, 2))
    [0.5 0.5 0.5]
    """
    readings, matrix = _check_inputs(powers, map_)
    weighted_map = noise_weighted_map(matrix, noise_std_w)
    if matrix.ndim == 2:
        u = cone_vectors(phase_rad)
        image = u @ matrix.T
        weighted = image if weighted_map is matrix else u @ weighted_map.T
    else:
        u = cone_vectors(_check_stacked_phase(phase_rad, readings.shape[0]))
        image = np.einsum("kji,ki->kj", matrix, u)
        weighted = image if weighted_map is matrix else np.einsum("kji,ki->kj", weighted_map, u)
    return _rows_dot(weighted, readings) / _rows_dot(weighted, image)


def pinv_phase_rad(powers, map_pinv) -> np.ndarray:
    """Pseudo-inverse phase ``atan2(x_2, x_1)`` (rad) of ``x = A+ p``, per reading.

    With one inverse it equals :func:`wavemeter.calibration.methods.learned.retrieve_phase_rad`.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Port readings (W).
    map_pinv : array_like, shape (3, n) or (N, 3, n)
        Moore-Penrose inverse ``A+`` of the map, or one per reading (:func:`stacked_pinv`).

    Returns
    -------
    ndarray, shape (N,), rad, in [-pi, pi]
    """
    readings, inverse = _check_pinv_inputs(powers, map_pinv)
    if inverse.ndim == 2:
        # two matrix-vector products keep both quadratures contiguous for the arctangent
        return np.arctan2(readings @ inverse[1], readings @ inverse[0])
    return np.arctan2(_rows_dot(readings, inverse[:, 1]), _rows_dot(readings, inverse[:, 0]))


def stacked_pinv(map_) -> np.ndarray:
    """Moore-Penrose inverses ``A_k+ = (A_k' A_k)^-1 A_k'`` (N, 3, n) of a stack of maps.

    Solved from the normal equations, batched: for N = 200000 maps of 5 ports about 7 times
    faster than ``np.linalg.pinv`` on the stack (an SVD per map), and as accurate for a map
    of rank 3 up to its condition number squared times the rounding unit (1e-13 for a
    condition number of 30, far below any map's calibration error).

    Parameters
    ----------
    map_ : array_like, shape (N, n, 3)
        One map per reading, each of rank 3 (W).

    Returns
    -------
    ndarray, shape (N, 3, n), 1/W
    """
    matrix = np.asarray(map_, dtype=float)
    if matrix.ndim != 3 or matrix.shape[2] != 3 or matrix.shape[1] < 3:
        raise InputError(
            f"map_ must have shape (N, n, 3) with n >= 3, got {matrix.shape}", parameter="map_"
        )
    if not np.all(np.isfinite(matrix)):
        raise InputError("map_ contains NaN or inf", parameter="map_")
    transposed = matrix.transpose(0, 2, 1)
    try:
        return np.linalg.solve(np.matmul(transposed, matrix), transposed)
    except np.linalg.LinAlgError as exc:
        raise InputError(
            "every map of map_ must have rank 3 (three independent columns)", parameter="map_"
        ) from exc
