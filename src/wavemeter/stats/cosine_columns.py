"""Discrete cosine columns projected off a fit, factored without being formed.

The discrete cosines are never formed: their products with the readings are DCTs (they are
orthogonal, and the product of two is half the sum of two others), so the nested QR factors
of the cosine columns with the fit projected out come from matrices of ``K`` plus the
number of fitted directions in size, and a test costs ``O(N)`` per channel instead of the
``O(N K^2)`` of a QR of ``N x K`` columns (:class:`CosineColumns`). For the columns that
couple the channels the fitted directions are ``r = c n + q`` arrays of N x n; beyond a
size they are applied through their structure, not formed
(:class:`ProjectedCosineColumns`: for a wide-band map of 15 columns and 3 phase
coefficients on 5 ports and 176000 readings, a report takes 0.9 s and 0.3 GB so; 27 s and
2.5 GB formed, as first measured with scipy's DCTs).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from .blocks import householder_qr, inner_products
from .cosine_transform import cosine_analysis, cosine_synthesis
from .projection import RANK_TOLERANCE, Columns, Projector

__all__ = ["MIN_OUTSIDE_GRAM", "CosineColumns", "ProjectedCosineColumns"]

#: smallest eigenvalue of the Gram matrix of the fitted directions' part outside the cosine
#: columns' span along which that part is not formed (:class:`ProjectedCosineColumns`)
MIN_OUTSIDE_GRAM = 1e-8


class CosineColumns(Columns):
    """Columns ``x_m(k) = b_m(k) D_k`` (the first K discrete cosines of the row times
    per-reading directions ``D``, N x p) projected off orthonormal directions ``Z`` (N, p, r),
    without forming them: every product with ``X`` is a DCT of N points.

    ``X'X = L L'`` is Toeplitz plus Hankel in the cosine transform of ``w_k = |D_k|^2``
    (``2 b_m b_l = b_{m-l} + b_{m+l}``; its condition number is at most ``max w / min w``),
    so ``U = X L^-T`` is orthonormal; the part of ``Z`` outside its span (Gram-Schmidt twice)
    has the QR factors ``V S``, ``Z = U T + V S``. In the frame ``[U, V]`` (M = K + r) the
    projected columns ``(I - Z Z') X`` are ``[L' - T Z'X; -S Z'X]``: the (K + r, K) matrix
    that Householder QR factors as it would the (N p, K) columns, to the same rounding
    relative to the columns' norms.
    """

    def __init__(self, direction, fitted: np.ndarray, orders: int, weight=None):
        self._factor_cosines(direction, fitted.shape[:2], orders, weight)
        cross = self._inner(fitted)  # X'Z (K, r)
        inside = self._solve(cross)
        outside = self._span(inside)
        np.subtract(fitted, outside, out=outside)
        step = self._solve(self._inner(outside))
        outside -= self._span(step)
        triangle, self.frame = householder_qr(outside.reshape(-1, outside.shape[2]), frame=True)
        self.matrix = np.vstack([self.factor.T - (inside + step) @ cross.T, -triangle @ cross.T])

    def _factor_cosines(self, direction, shape, orders: int, weight=None) -> None:
        """The direction (N, p; None: 1 on each port alone, p = 1) and its squared norms
        ``weight`` (N,; None: computed), and the Cholesky factor ``L`` and norms of the
        columns' Gram."""
        self.direction = direction
        self.shape = shape
        if direction is not None and weight is None:
            weight = np.einsum("ij,ij->i", direction, direction)
        if weight is None or np.all(weight == weight[0]):  # the cosines are orthogonal
            moments = np.zeros(2 * orders + 1)
            moments[0] = shape[0] * (1.0 if weight is None else weight[0])
        else:
            moments = cosine_analysis(weight, 2 * orders + 1)
        index = np.arange(1, orders + 1)
        gram = 0.5 * (moments[np.abs(index[:, None] - index)] + moments[index[:, None] + index])
        self.factor = linalg.cholesky(gram, lower=True, check_finite=False)
        self.norms = np.sqrt(np.diag(gram))

    def _solve(self, values: np.ndarray, transposed: bool = False) -> np.ndarray:
        """``L^-1 v``, or ``L^-T v`` (``transposed``)."""
        return linalg.solve_triangular(
            self.factor, values, trans=int(transposed), lower=True, check_finite=False
        )

    def _inner(self, values: np.ndarray) -> np.ndarray:
        """``X' v`` for ``values`` (N, p, t): (K, t)."""
        if self.direction is None:
            rows = values[:, 0, :]
        else:  # each column's readings contiguous (the transform runs down the readings)
            rows = np.einsum("kp,kpt->tk", self.direction, values).T
        return cosine_analysis(rows, self.factor.shape[0] + 1)[1:]

    def _span(self, coefficients: np.ndarray) -> np.ndarray:
        """``U c`` for ``coefficients`` (K, t): (N, p, t), the readings and ports of each
        column contiguous (Fortran order in (N p, t))."""
        rows = cosine_synthesis(self._solve(coefficients, transposed=True), self.shape[0])
        if self.direction is None:
            return rows[:, None, :]
        vectors = np.empty((coefficients.shape[1],) + self.shape).transpose(1, 2, 0)
        return np.multiply(self.direction[:, :, None], rows[:, None, :], out=vectors)

    def coordinates(self, values: np.ndarray) -> np.ndarray:
        inside = self._solve(self._inner(values))
        return np.vstack([inside, inner_products(self.frame, values.reshape(-1, values.shape[2]))])

    def _along(self, coefficients: np.ndarray) -> np.ndarray:
        """``(U c)_k D_k / w_k`` (N,) for ``coefficients`` (K,): the cosine sum itself."""
        return cosine_synthesis(self._solve(coefficients[:, None], transposed=True), self.shape[0])[
            :, 0
        ]

    def amplitude(self, coordinates: np.ndarray, direction: np.ndarray, weight) -> np.ndarray:
        orders = self.factor.shape[0]
        outside = (self.frame @ coordinates[orders:]).reshape(self.shape)
        return (
            self._along(coordinates[:orders]) + np.einsum("ij,ij->i", outside, direction) / weight
        )


class ProjectedCosineColumns(CosineColumns):
    """:class:`CosineColumns` projected off the directions ``Z`` of a :class:`Projector`
    (orthonormal, ``r`` = ``c n + q`` arrays N x n) without forming them all: their products
    come from the projector's structure (one basis on every port), and the frame of their
    part outside the cosine columns' span from its Gram matrix.

    With ``T = U'Z`` (``L^-1 X'Z``, K x r), the part ``Z - U T`` has the Gram matrix ``G = I
    - T'T = E diag(s^2) E'``, and ``V = (Z - U T) E diag(1/s)`` is orthonormal: in the frame
    ``[U, V]`` the projected columns are ``[L' - T Z'X; -diag(s) E' Z'X]``. ``G`` holds an
    ``s^2`` only to ``~1e-16`` absolutely, so ``V`` is taken where ``s^2 >=
    MIN_OUTSIDE_GRAM`` (errors below ``1e-10`` of the columns' norms, 1 % of
    ``RANK_TOLERANCE``). The other directions ``Z e`` lie nearly inside the span (a phase
    polynomial whose cosine series converges fast): their part outside ``U`` and ``V`` is
    formed (Gram-Schmidt twice), as :class:`CosineColumns` forms all, and kept where it
    exceeds ``RANK_TOLERANCE`` of ``|Z e| = 1``, orthonormal (``F``, N n x b; rows ``F'X -
    F'Z Z'X``). Cost ``O(N n (r + K b))`` and memory ``O(N (K + r + n b))`` against the ``O(N
    n r^2)`` and ``O(N n r)`` of forming ``Z``.
    """

    def __init__(self, direction: np.ndarray, projector: Projector, orders: int, weight=None):
        self._factor_cosines(direction, direction.shape, orders, weight)
        self.projector = projector
        # X'Z (K, r), port by port: the basis on that port alone (its columns contiguous)
        products = np.empty((projector.basis.shape[1], direction.shape[0]))
        cross = []
        for port in range(direction.shape[1]):
            np.multiply(projector.basis.T, direction[:, port], out=products)
            cross.append(cosine_analysis(products.T, orders + 1)[1:])
        cross = np.hstack(cross + [self._inner(projector.coupled)])
        self.inside = self._solve(cross)  # T
        squares, rotation = linalg.eigh(np.eye(cross.shape[1]) - self.inside.T @ self.inside)
        accurate = squares >= MIN_OUTSIDE_GRAM
        self.rotation, self.outside_norms = rotation[:, accurate], np.sqrt(squares[accurate])
        self.frame = self._formed_frame(rotation[:, ~accurate])
        formed = self.frame.reshape(self.shape + (-1,))
        self.matrix = np.vstack(
            [
                self.factor.T - self.inside @ cross.T,
                -self.outside_norms[:, None] * (self.rotation.T @ cross.T),
                self._inner(formed).T - projector.inner(formed).T @ cross.T,
            ]
        )

    def _formed_frame(self, nearly_inside: np.ndarray) -> np.ndarray:
        """Orthonormal frame (N n, b) of the part of ``Z e`` (``e`` the columns of
        ``nearly_inside``, r x m) outside the span of ``U`` and ``V``."""
        rows = self.shape[0] * self.shape[1]
        if nearly_inside.shape[1] == 0:
            return np.zeros((rows, 0))
        formed = self.projector.span(nearly_inside) - self._span(self.inside @ nearly_inside)
        for _ in range(2):
            formed = self._off_frame(formed)
        frame, sizes, _ = linalg.svd(formed.reshape(rows, -1), full_matrices=False)
        kept = frame[:, sizes > RANK_TOLERANCE]
        if kept.shape[1] == 0:  # every one of them inside after all
            return np.zeros((rows, 0))
        frame = self._off_frame(kept.reshape(self.shape + (kept.shape[1],)))
        return linalg.qr(frame.reshape(rows, -1), mode="economic")[0]

    def _off_frame(self, values: np.ndarray) -> np.ndarray:
        """``values`` (N, n, t) less their parts along ``U`` and ``V``."""
        values = values - self._span(self._solve(self._inner(values)))
        return values - self._outside_vectors(self._outside_coordinates(values))

    def _outside_coordinates(self, values: np.ndarray, inside=None) -> np.ndarray:
        """``V' v`` (s, t) of ``values`` (N, n, t) (with their ``U' v``, ``inside``)."""
        if inside is None:
            inside = self._solve(self._inner(values))
        along = self.rotation.T @ (self.projector.inner(values) - self.inside.T @ inside)
        return along / self.outside_norms[:, None]

    def _outside_vectors(self, coordinates: np.ndarray) -> np.ndarray:
        """``V c`` (N, n, t) for ``coordinates`` (s, t): ``(Z - U T) E diag(1/s) c``."""
        along = self.rotation @ (coordinates / self.outside_norms[:, None])
        return self.projector.span(along) - self._span(self.inside @ along)

    def coordinates(self, values: np.ndarray) -> np.ndarray:
        inside = self._solve(self._inner(values))
        return np.vstack(
            [
                inside,
                self._outside_coordinates(values, inside),
                self.frame.T @ values.reshape(-1, values.shape[2]),
            ]
        )

    def amplitude(self, coordinates: np.ndarray, direction: np.ndarray, weight) -> np.ndarray:
        orders, outside = self.factor.shape[0], self.outside_norms.size
        inside, along, formed = np.split(coordinates, [orders, orders + outside])
        along = self.rotation @ (along / self.outside_norms)
        amplitude = self._along(inside - self.inside @ along)
        amplitude += self.projector.span_along(along, direction) / weight
        if formed.size:
            formed = (self.frame @ formed).reshape(self.shape)
            amplitude += np.einsum("ij,ij->i", formed, direction) / weight
        return amplitude
