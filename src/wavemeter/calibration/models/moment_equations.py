"""The learned fit's normal equations from a sweep's binned moments, at any trial delay.

:class:`MomentEquationsMixin` turns the harmonic sums of
:class:`~wavemeter.calibration.models.moments.FringeMoments` into the normal equations of
the objects ``Rxx``, ``Rxp`` (and those of their delay derivative): ``J`` and its delay
derivative, the least-squares map, each port's residual power, the products of the
objects for the covariance, and the Gauss-Newton curvature in the delay.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

__all__ = ["MomentEquationsMixin"]

#: cone columns of the object vector as combinations of ``e^{i k t}``, ``k = -1, 0, 1``
_CONE = np.array([[0.5, 0.0, 0.5], [0.5j, 0.0, -0.5j], [0.0, np.sqrt(2.0), 0.0]])
_HARMONICS = np.array([-1, 0, 1])
#: ``d / dtau`` of those columns, per unit of ``(f - f0)``: ``2 pi i k``
_CONE_SLOPE = _CONE * (2j * np.pi * _HARMONICS)


def _solve(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``gram^-1 rhs`` for a symmetric positive (semi)definite ``gram``, columns equilibrated
    (any monitor unit), rank-revealing (LAPACK ``gelsy``) like the direct fit."""
    norm = np.sqrt(np.diag(gram))
    norm[norm == 0] = 1.0
    solution, *_ = linalg.lstsq(
        gram / np.outer(norm, norm), rhs / norm[:, None], lapack_driver="gelsy", check_finite=False
    )
    return solution / norm[:, None]


class MomentEquationsMixin:
    """The normal equations of the learned fit from the moments (module docstring)."""

    def _normal(self, sums: np.ndarray, affine: bool) -> tuple[np.ndarray, np.ndarray]:
        """``Rxx`` (k, k) and ``Rxp`` (k, n) from :meth:`harmonic_sums` ``[0]``."""
        ports = self._ports
        gram = np.zeros((4, 4) if affine else (3, 3))
        cross = np.zeros((gram.shape[0], ports))
        gram[:3, :3] = _pair(_CONE, _CONE, sums[:, 0])
        cross[:3] = (_CONE @ sums[_HARMONICS + 2, 1 : ports + 1]).real
        if affine:
            gram[:3, 3] = gram[3, :3] = (_CONE @ sums[_HARMONICS + 2, ports + 1]).real
            gram[3, 3] = self._samples
            cross[3] = self._sum_powers
        return gram, cross

    def _slopes(self, sums: np.ndarray, affine: bool) -> tuple[np.ndarray, np.ndarray]:
        """``D^T X`` (k, k) and ``D^T P`` (k, n) from :meth:`harmonic_sums` ``[1]``."""
        ports = self._ports
        columns = 4 if affine else 3
        slope = np.zeros((columns, columns))
        cross = np.zeros((columns, ports))
        slope[:3, :3] = _pair(_CONE_SLOPE, _CONE, sums[:, 0])
        cross[:3] = (_CONE_SLOPE @ sums[_HARMONICS + 2, 1 : ports + 1]).real
        if affine:
            slope[:3, 3] = (_CONE_SLOPE @ sums[_HARMONICS + 2, ports + 1]).real
        return slope, cross

    def cost(self, delay_s: float, affine: bool = False) -> float:
        """Learned-map cost ``J = min_A mean ||p - A x||^2`` (W^2) at ``delay_s`` (s).

        Equals :func:`~wavemeter.calibration.models.linear_map.map_cost` to a few ``2^-53``
        ``sum |p|^2 / N``; clipped at 0 (rounding can make it negative on noiseless data).
        """
        gram, cross = self._normal(self.harmonic_sums(delay_s, 0)[0], affine)
        solution = _solve(gram, cross)
        return max(float(self._power2 - np.einsum("ij,ij->", cross, solution)) / self._samples, 0.0)

    def cost_derivative(self, delay_s: float, affine: bool = False) -> float:
        """``dJ / dtau`` (W^2/s) at ``delay_s`` (s), the map profiled out (envelope theorem).

        ``-2 tr(B^T (D^T P - D^T X B)) / N`` with ``B = Rxx^-1 Rxp``; no cancellation at the
        minimum of ``J``, where it changes sign.
        """
        sums = self.harmonic_sums(delay_s, 1)
        gram, cross = self._normal(sums[0], affine)
        slope, slope_cross = self._slopes(sums[1], affine)
        solution = _solve(gram, cross)
        residual = slope_cross - slope @ solution
        return -2.0 * float(np.einsum("ij,ij->", solution, residual)) / self._samples

    def map_at(self, delay_s: float, affine: bool = False) -> np.ndarray:
        """Least-squares map ``A = Rxp^T Rxx^-1`` (n, 3), or (n, 4) with ``affine`` (W)."""
        gram, cross = self._normal(self.harmonic_sums(delay_s, 0)[0], affine)
        return _solve(gram, cross).T

    def unfitted_cost(self, affine: bool = False) -> float:
        """Cost ``J`` (W^2) of the model with no fringe: the cone axis (and offsets) alone.

        As :func:`~wavemeter.calibration.models.linear_map.unfitted_cost`.
        """
        gram, cross = self._normal(self.harmonic_sums(0.0, 0)[0], affine)
        keep = [2, 3] if affine else [2]
        solution = _solve(gram[np.ix_(keep, keep)], cross[keep])
        return float(self._power2 - np.einsum("ij,ij->", cross[keep], solution)) / self._samples

    def object_gram(self, delay_s: float, affine: bool = False):
        """The object matrix ``X`` and its delay derivative ``D`` through their products.

        Parameters
        ----------
        delay_s : float
            Delay (s).
        affine : bool
            With the column of ones (per-port offsets), whose derivative is 0.

        Returns
        -------
        xx, dx, dd : ndarray, shape (k, k)
            ``X^T X``, ``D^T X`` and ``D^T D`` (``k`` = 3, or 4 with ``affine``), in the
            units of the scale squared times 1, 1/s and 1/s^2.
        """
        sums = self.harmonic_sums(delay_s, 2)
        gram, _ = self._normal(sums[0], affine)
        slope, _ = self._slopes(sums[1], affine)
        curvature = np.zeros_like(gram)
        curvature[:3, :3] = _pair(_CONE_SLOPE, _CONE_SLOPE, sums[2][:, 0])
        return gram, slope, curvature

    def port_residual_w2(self, delay_s: float, map_: np.ndarray) -> np.ndarray:
        """Each port's summed squared residual ``sum_i (p_ij - A_j x_i)^2`` (W^2) under a map.

        ``sum p_j^2 - 2 A_j (Rxp)_j + A_j Rxx A_j^T``: it cancels like :meth:`cost` (an
        absolute error of a few ``2^-53 sum p_j^2``); clipped at 0.

        Parameters
        ----------
        delay_s : float
            Delay (s).
        map_ : ndarray, shape (n, 3) or (n, 4)
            Map (W) for the scale as given; a fourth column makes it affine.

        Returns
        -------
        ndarray, shape (n,)
        """
        solution = np.asarray(map_, dtype=float).T
        gram, cross = self._normal(self.harmonic_sums(delay_s, 0)[0], solution.shape[0] == 4)
        energy = (
            self._port_power2
            - 2.0 * np.einsum("ij,ij->j", solution, cross)
            + np.einsum("ij,ij->j", solution, gram @ solution)
        )
        return np.maximum(energy, 0.0)

    def delay_information(self, delay_s: float, map_: np.ndarray) -> float:
        """Gauss-Newton curvature ``G`` (W^2/s^2) of the summed squared residual in the delay.

        As :func:`~wavemeter.calibration.models.linear_map.delay_information`:
        ``G = ||(I - Pi_X) D A^T||_F^2 = tr(B^T D^T D B) - tr(V^T Rxx^-1 V)``, ``B = A^T``,
        ``V = X^T D B``.

        Parameters
        ----------
        delay_s : float
            Delay (s).
        map_ : ndarray, shape (n, 3) or (n, 4)
            Map at that delay (W) for the scale as given; a fourth column makes it affine.
        """
        solution = np.asarray(map_, dtype=float).T
        gram, slope, curvature = self.object_gram(delay_s, solution.shape[0] == 4)
        projected = slope.T @ solution
        return float(
            np.einsum("ij,ij->", solution, curvature @ solution)
            - np.einsum("ij,ij->", projected, _solve(gram, projected))
        )


def _pair(left: np.ndarray, right: np.ndarray, sums: np.ndarray) -> np.ndarray:
    """``Re sum_{k1, k2} left[a, k1] right[b, k2] Z(k1 + k2)`` for ``Z(k)``, ``k = -2..2``."""
    hankel = sums[_HARMONICS[:, None] + _HARMONICS[None, :] + 2]
    return (left @ hankel @ right.T).real
