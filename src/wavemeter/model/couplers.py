"""Ideal coupler transmission matrices and the ideal orthonormal map of a design.

Conventions: a transmission matrix ``M`` (complex, ``n x n``) maps the field amplitudes at
the ingress ports to those at the egress ports, ``c = M @ b`` (paper Eq. 1). Port indices
are zero-based in code; the paper and datasheets count from one.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError, shown

__all__ = [
    "fourier_matrix",
    "mmi_matrix",
    "mmi_2x2",
    "y_junction",
    "port_phases_rad",
    "orthonormal_map",
    "equally_spaced_phases_rad",
]


def _check_port_count(n: int, minimum: int) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise InputError(f"ports must be an integer, got {type(n).__name__} {shown(n)}")
    if n < minimum:
        raise InputError(f"ports must be >= {minimum}, got {n}")
    return int(n)


def fourier_matrix(n: int) -> np.ndarray:
    """Unitary ``n x n`` discrete Fourier matrix of the paper's Eq. 5.

    ``F[p, q] = w**(p*q) / sqrt(n)`` with ``w = exp(-2j*pi/n)``.

    Parameters
    ----------
    n : int
        Number of ports, ``n >= 2``.

    Returns
    -------
    ndarray of complex, shape (n, n)

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> F = wm.fourier_matrix(3)
    >>> print(np.allclose(F @ F.conj().T, np.eye(3)))  # unitary
    True
    >>> print(np.round(np.abs(F) ** 2, 3))  # every output gets a third of every input
    [[0.333 0.333 0.333]
     [0.333 0.333 0.333]
     [0.333 0.333 0.333]]
    """
    n = _check_port_count(n, 2)
    k = np.arange(n)
    return np.exp(-2j * np.pi * np.outer(k, k) / n) / np.sqrt(n)


def mmi_matrix(n: int) -> np.ndarray:
    """Transmission matrix of an ideal ``n x n`` general-interference MMI coupler.

    Uses the self-imaging phase formula of Bachmann, Besse and Melchior (Appl. Opt. 33,
    3905, 1994): from ingress port ``i`` to egress port ``j`` (both counted from one),
    the amplitude is ``exp(1j*phi_ij)/sqrt(n)`` with

    - ``phi_ij = pi + pi/(4n) (j - i)(2n - j + i)`` when ``i + j`` is even,
    - ``phi_ij = pi/(4n) (i + j - 1)(2n - j - i + 1)`` when ``i + j`` is odd,

    dropping the common phase. The result is unitary and phase-permutation equivalent to
    :func:`fourier_matrix`.

    Parameters
    ----------
    n : int
        Number of ports, ``n >= 2``.

    Returns
    -------
    ndarray of complex, shape (n, n)
        ``M[j, i]``: egress ``j`` from ingress ``i`` (zero-based).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> M = wm.mmi_matrix(3)
    >>> print(np.allclose(M @ M.conj().T, np.eye(3)))  # lossless
    True
    >>> fringes = np.angle(M[:, 0] / M[:, 2])  # inputs 1 and 3 feed the arms
    >>> print(np.round(np.degrees(np.sort(fringes)), 1))  # port phases 120 degrees apart
    [-120.    0.  120.]
    """
    n = _check_port_count(n, 2)
    i = np.arange(1, n + 1)[np.newaxis, :]  # ingress, columns
    j = np.arange(1, n + 1)[:, np.newaxis]  # egress, rows
    even = (i + j) % 2 == 0
    phase_even = np.pi + np.pi / (4 * n) * (j - i) * (2 * n - j + i)
    phase_odd = np.pi / (4 * n) * (i + j - 1) * (2 * n - j - i + 1)
    return np.exp(1j * np.where(even, phase_even, phase_odd)) / np.sqrt(n)


def mmi_2x2() -> np.ndarray:
    """Ideal 2x2 MMI (3 dB) coupler, shape (2, 2); used as an input splitter."""
    return mmi_matrix(2)


def y_junction() -> np.ndarray:
    """Ideal Y-junction splitter as a (2, 1) matrix: equal in-phase amplitudes 1/sqrt(2)."""
    return np.full((2, 1), 1.0 / np.sqrt(2.0), dtype=complex)


def port_phases_rad(output_coupler: np.ndarray, inputs: tuple[int, int]) -> np.ndarray:
    """Fringe phase of every egress port when the coupler is fed at two ingress ports.

    Port ``j`` sees ``|M[j,a] e1 + M[j,b] e2|^2``, a fringe ``1 + cos(theta - phi_j)`` in
    the phase ``theta`` of ``e1`` relative to ``e2``; this returns
    ``phi_j = -arg(M[j,a] conj(M[j,b]))`` wrapped to (-pi, pi].

    Parameters
    ----------
    output_coupler : ndarray of complex, shape (n, n)
    inputs : (int, int)
        Zero-based ingress ports fed by the delayed arm and the reference arm.

    Returns
    -------
    ndarray of float, shape (n,), rad
    """
    matrix = np.asarray(output_coupler, dtype=complex)
    a, b = inputs
    return -np.angle(matrix[:, a] * np.conj(matrix[:, b]))


def equally_spaced_phases_rad(n: int) -> np.ndarray:
    """Port phases ``2 pi j / n`` for ``j = 0..n-1`` (rad), the default nominal design."""
    n = _check_port_count(n, 3)
    return 2.0 * np.pi * np.arange(n) / n


def orthonormal_map(phases_rad) -> np.ndarray:
    """Ideal map ``O`` (n x 3) of a design from its nominal port phases (Eq. 15-16).

    Columns ``sqrt(2/n) cos(phi)``, ``sqrt(2/n) sin(phi)`` and ``1/sqrt(n)``. For phases
    equally spaced over the circle (any order) ``O.T @ O`` is the identity.

    Parameters
    ----------
    phases_rad : array_like, shape (n,)
        Nominal fringe phase of each port, ``n >= 3``.

    Returns
    -------
    ndarray of float, shape (n, 3)

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> O = wm.orthonormal_map(np.radians([0.0, 120.0, 240.0]))
    >>> O.shape
    (3, 3)
    >>> print(np.allclose(O.T @ O, np.eye(3)))
    True
    """
    phases = np.asarray(phases_rad, dtype=float)
    if phases.ndim != 1:
        raise InputError(f"port phases must be a 1-D array, got shape {phases.shape}")
    n = _check_port_count(phases.size, 3)
    if not np.all(np.isfinite(phases)):
        raise InputError("port phases must be finite numbers (rad)")
    scale = np.sqrt(2.0 / n)
    return np.column_stack(
        [scale * np.cos(phases), scale * np.sin(phases), np.full(n, 1.0 / np.sqrt(n))]
    )
