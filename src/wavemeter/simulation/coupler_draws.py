"""Gaussian draws of output-coupler changes that respect the symmetries of an MMI.

Table 1 scales the real and imaginary parts of each coupler entry by ``1 + g + e``: ``g`` is
shared by the entries the MMI symmetry makes equal, ``e`` is drawn per entry. The spectral
slopes of the coupler (:mod:`wavemeter.simulation.spectral_presets`) are drawn the same way.
"""

from __future__ import annotations

import numpy as np

__all__ = ["orbit_changes", "perturb_coupler", "symmetry_classes"]


def symmetry_classes(n: int) -> np.ndarray:
    """Label each entry of an ``n x n`` MMI matrix by its orbit under the MMI symmetries.

    A general-interference MMI is reciprocal (``M[j, i] == M[i, j]``) and mirror symmetric
    about its centre (``M[j, i] == M[n-1-j, n-1-i]``); entries one of these maps onto
    another are equal, and share the symmetry-preserving perturbation.
    """
    labels = -np.ones((n, n), dtype=int)
    next_label = 0
    for j in range(n):
        for i in range(n):
            if labels[j, i] >= 0:
                continue
            orbit = {(j, i), (i, j), (n - 1 - j, n - 1 - i), (n - 1 - i, n - 1 - j)}
            for a, b in orbit:
                labels[a, b] = next_label
            next_label += 1
    return labels


def orbit_changes(
    n: int, rng: np.random.Generator, symmetric_sigma: float, breaking_sigma: float
) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian relative changes of the real and imaginary parts of an ``n x n`` MMI matrix.

    Returns
    -------
    shared : ndarray of complex, shape (n, n)
        ``g_re + 1j g_im``, sigma ``symmetric_sigma`` each, shared by the entries of one
        symmetry orbit (see :func:`symmetry_classes`).
    own : ndarray of complex, shape (n, n)
        ``e_re + 1j e_im``, sigma ``breaking_sigma`` each, drawn per entry.
    """
    labels = symmetry_classes(n)
    classes = labels.max() + 1
    shared_re = rng.normal(0.0, symmetric_sigma, classes)[labels]
    shared_im = rng.normal(0.0, symmetric_sigma, classes)[labels]
    own_re = rng.normal(0.0, breaking_sigma, (n, n))
    own_im = rng.normal(0.0, breaking_sigma, (n, n))
    return shared_re + 1j * shared_im, own_re + 1j * own_im


def perturb_coupler(
    matrix: np.ndarray, rng: np.random.Generator, symmetric_sigma: float, breaking_sigma: float
) -> np.ndarray:
    """Scale real and imaginary parts by Gaussian factors (Table 1).

    Factor ``1 + g + e``: ``g`` (sigma ``symmetric_sigma``) is shared by the entries of one
    symmetry orbit, ``e`` (sigma ``breaking_sigma``) is drawn per entry
    (:func:`orbit_changes`).
    """
    shared, own = orbit_changes(matrix.shape[0], rng, symmetric_sigma, breaking_sigma)
    return matrix.real * (1.0 + shared.real + own.real) + 1j * matrix.imag * (
        1.0 + shared.imag + own.imag
    )
