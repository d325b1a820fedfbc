"""Cone-constrained maximum-likelihood phase retrieval and per-reading uncertainty.

The paper retrieves phase from the unconstrained object estimate ``x_hat = A+ p`` (three
free values). The readings, though, come from a point on the cone,
``p = P A u(t) + noise`` with ``u(t) = [cos t, sin t, sqrt 2]``: two unknowns. With white
Gaussian detector noise the maximum-likelihood estimate minimises ``|p - P A u(t)|^2``; for a
given ``t`` the best power is ``P = (u . b) / (u' M u)`` (``b = A' p``, ``M = A' A``), which
leaves the one-dimensional problem of maximising

    h(t) = 2 log(u . b) - log(u' M u).

Starting from the pseudo-inverse phase, a few Newton steps on ``h`` converge per reading.
The estimate reaches the Cramer-Rao bound where the pseudo-inverse does not: an ideal map
makes the two coincide, an ill-conditioned one (a weak port) separates them.
"""

from __future__ import annotations

import numpy as np

from .cone import cone_vectors, wrap_phase_rad

__all__ = ["cone_ml_phase_rad", "source_power_ratio", "MAX_NEWTON_STEP_RAD"]

#: Newton steps are clipped to this size (rad); near the optimum they are far smaller
MAX_NEWTON_STEP_RAD = 0.5


def _rows_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def cone_ml_phase_rad(powers, map_: np.ndarray, start_rad, iterations: int = 3) -> np.ndarray:
    """Maximum-likelihood phase (rad) of readings constrained to the image of the cone.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Port readings (W).
    map_ : ndarray, shape (n, 3)
        The map ``A``.
    start_rad : array_like, shape (N,)
        Starting phase, e.g. the pseudo-inverse phase.
    iterations : int
        Newton steps; each step roughly squares the distance to the optimum.

    Returns
    -------
    ndarray, shape (N,), rad, wrapped to [-pi, pi)
    """
    readings = np.asarray(powers, dtype=float)
    matrix = np.asarray(map_, dtype=float)
    gram = matrix.T @ matrix
    projected = readings @ matrix  # rows b = A' p
    phase = np.array(start_rad, dtype=float)
    zeros = np.zeros_like(phase)
    for _ in range(iterations):
        u = cone_vectors(phase)
        cos, sin = u[:, 0], u[:, 1]
        du = np.stack([-sin, cos, zeros], axis=1)
        ddu = np.stack([-cos, -sin, zeros], axis=1)
        gram_u, gram_du = u @ gram, du @ gram
        num, num_1, num_2 = (
            _rows_dot(u, projected),
            _rows_dot(du, projected),
            _rows_dot(ddu, projected),
        )
        den = _rows_dot(u, gram_u)
        den_1 = 2.0 * _rows_dot(du, gram_u)
        den_2 = 2.0 * (_rows_dot(ddu, gram_u) + _rows_dot(du, gram_du))
        # a maximum has negative curvature; elsewhere (far from it, or where the reading
        # has no projection on the cone: u . b = 0) do not step
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            slope = 2.0 * num_1 / num - den_1 / den
            curvature = 2.0 * (num_2 * num - num_1**2) / num**2 - (den_2 * den - den_1**2) / den**2
            step = np.where(curvature < 0, -slope / np.where(curvature < 0, curvature, -1.0), 0.0)
        step = np.where(np.isfinite(step), step, 0.0)
        phase = phase + np.clip(step, -MAX_NEWTON_STEP_RAD, MAX_NEWTON_STEP_RAD)
    return wrap_phase_rad(phase)


def source_power_ratio(powers, map_: np.ndarray, phase_rad) -> np.ndarray:
    """Least-squares source power of each reading relative to the map's power (unitless).

    ``P = (u . A' p) / (u' A' A u)`` at the given phase: 1 for a reading at the power the
    map was learned at (with a power monitor, at the mean monitored power).
    """
    readings = np.asarray(powers, dtype=float)
    matrix = np.asarray(map_, dtype=float)
    image = cone_vectors(phase_rad) @ matrix.T
    return _rows_dot(image, readings) / _rows_dot(image, image)
