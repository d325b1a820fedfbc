"""The statistics of the fit diagnostics: model-free noise and nested cosine tests.

:mod:`wavemeter.calibration.misfit` asks whether a calibration residual holds structure
that white noise would not: after the fit is projected out, the residual's energy along
nested sets of discrete cosines of the row index (smooth in time) or of the fringe phase
is tested against the model-free noise with F tests (:class:`ResidualTests`). The
model-free noise comes from second differences of the residual, corrected for the fit
(:func:`model_free_noise`).

The discrete cosines are never formed: their products with the readings are DCTs (they are
orthogonal, and the product of two is half the sum of two others), so the nested QR
factors of the cosine columns with the fit projected out come from matrices of ``K`` plus
the number of fitted directions in size, and a report costs ``O(N log N)`` per port and per
test instead of the ``O(N K^2)`` of a QR of ``N x K`` columns (:class:`CosineColumns`). Short
sweeps (``MIN_DCT_READINGS``) and per-reading directions too uneven for the cosines' Gram
matrix (``MIN_GRAM_WEIGHT``) form the columns instead.

What the fit absorbs (:class:`Projector`) is each port's fitted columns and one direction
per nonlinear parameter shared by the ports (the delay; a phase polynomial's coefficients).
For the tests that couple the ports these are ``r = c n + q`` arrays of N x n: formed while
they hold at most ``MAX_FORMED_DIRECTIONS`` numbers, applied through their structure beyond
(:class:`ProjectedCosineColumns`: for a wide-band map of 15 columns and 3 phase coefficients
on 5 ports and 176000 readings, a report takes 2 s and 0.4 GB so, 27 s and 2.5 GB formed).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import fft, linalg, special

__all__ = [
    "TEST_P_VALUE",
    "RANK_TOLERANCE",
    "MIN_GRAM_WEIGHT",
    "MIN_DCT_READINGS",
    "MAX_FORMED_DIRECTIONS",
    "MIN_OUTSIDE_GRAM",
    "model_free_noise",
    "Projector",
    "Columns",
    "CosineColumns",
    "ProjectedCosineColumns",
    "projected_components",
    "ResidualTest",
    "ResidualTests",
]

#: false-alarm probability of each test for in-model data
TEST_P_VALUE = 1e-6
#: relative size under which a projected column counts as absorbed by the fit
RANK_TOLERANCE = 1e-8
#: smallest squared norm of a reading's direction, relative to the largest, for which cosine
#: columns are orthonormalised through their Gram matrix (its condition number is at most
#: the inverse); below, they are formed and factored explicitly
MIN_GRAM_WEIGHT = 1e-6
#: fewest readings for which cosine columns are factored through DCTs (not formed)
MIN_DCT_READINGS = 128
#: most numbers (N n r) in the fitted directions formed for the tests coupling the ports
#: (134 MB); beyond, they are applied through their structure (:class:`ProjectedCosineColumns`)
MAX_FORMED_DIRECTIONS = 2**24
#: smallest eigenvalue of the Gram matrix of the fitted directions' part outside the cosine
#: columns' span along which that part is not formed (:class:`ProjectedCosineColumns`)
MIN_OUTSIDE_GRAM = 1e-8


def _second_difference_adjoint(values: np.ndarray) -> np.ndarray:
    """``D' y`` for second differences ``D`` (rows): (N - 2, ...) -> (N, ...)."""
    padding = [(2, 2)] + [(0, 0)] * (values.ndim - 1)
    return np.diff(np.pad(values, padding), n=2, axis=0)


def model_free_noise(residual: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, float]:
    """Second-difference noise per port (W) and its degrees of freedom.

    ``T = trace(D (I - H) D')`` and ``trace((D (I - H) D')^2)`` are computed from the band
    matrix ``D D'`` (6, -4, 1) and the low-rank ``U = D Q`` without forming N x N matrices.
    """
    samples = residual.shape[0]
    differences = np.diff(residual, n=2, axis=0)
    low_rank = np.diff(basis, n=2, axis=0)
    trace = 6.0 * (samples - 2) - np.einsum("ij,ij->", low_rank, low_rank)
    band = 36.0 * (samples - 2) + 32.0 * max(samples - 3, 0) + 2.0 * max(samples - 4, 0)
    spread = _second_difference_adjoint(low_rank)
    gram = low_rank.T @ low_rank
    trace_square = band - 2.0 * np.einsum("ij,ij->", spread, spread) + np.sum(gram**2)
    noise = np.sqrt(np.einsum("ij,ij->j", differences, differences) / trace)
    return noise, float(trace**2 / trace_square)


def _cosines(samples: int, orders: int) -> np.ndarray:
    """The first ``orders`` discrete cosines ``cos(pi m (k + 1/2) / N)``, m = 1.. (N, K)."""
    index = np.arange(samples) + 0.5
    return np.cos(np.pi * np.outer(index, np.arange(1, orders + 1)) / samples)


def _cosine_analysis(values: np.ndarray, orders: int) -> np.ndarray:
    """``sum_k b_m(k) v_k`` for ``m = 0..orders - 1`` (DCT-II): (N, ...) -> (orders, ...)."""
    return fft.dct(values, type=2, axis=0)[:orders] / 2.0


def _cosine_synthesis(coefficients: np.ndarray, samples: int) -> np.ndarray:
    """``sum_m c_m b_m(k)`` for ``m = 1..K`` (DCT-III): (K, ...) -> (N, ...)."""
    padded = np.zeros((samples,) + coefficients.shape[1:])
    padded[1 : coefficients.shape[0] + 1] = coefficients / 2.0
    return fft.dct(padded, type=3, axis=0)


class Projector:
    """Projects whitened (N, n, ...) arrays off what the fit absorbs: each port's fitted
    columns (orthonormal ``basis``, N x c) and the directions of the nonlinear parameters
    shared by the ports (``coupled``, (N, n, q): each couples the ports; the delay alone for
    one map). These are orthonormalised jointly, in order, off the fitted columns (Gram-Schmidt
    twice against the ones before); one that those absorb (to ``RANK_TOLERANCE`` of its norm)
    is dropped."""

    def __init__(self, basis: np.ndarray, coupled: np.ndarray):
        self.basis = basis
        projected = self.per_port(coupled)
        norms = np.sqrt(np.einsum("ijk,ijk->k", coupled, coupled))
        kept = []
        for index, norm in enumerate(norms):
            column = np.ascontiguousarray(projected[:, :, index])
            for _ in range(2):
                for previous in kept:
                    column -= np.einsum("ij,ij->", previous, column) * previous
            remaining = np.sqrt(np.einsum("ij,ij->", column, column))
            if remaining > RANK_TOLERANCE * norm:
                kept.append(column / remaining)
        self.coupled = np.stack(kept, axis=2) if kept else np.zeros(coupled.shape[:2] + (0,))

    def per_port(self, values: np.ndarray) -> np.ndarray:
        return values - np.tensordot(
            self.basis, np.tensordot(self.basis, values, axes=(0, 0)), axes=(1, 0)
        )

    def __call__(self, values: np.ndarray) -> np.ndarray:
        projected = self.per_port(values)
        along = np.tensordot(self.coupled, projected, axes=([0, 1], [0, 1]))
        return projected - np.tensordot(self.coupled, along, axes=(2, 0))

    @property
    def size(self) -> int:
        """Number of directions removed: ``c n`` fitted columns and the coupled ones kept."""
        return self.basis.shape[1] * self.coupled.shape[1] + self.coupled.shape[2]

    def inner(self, values: np.ndarray) -> np.ndarray:
        """Coordinates ``Z' v`` (:attr:`size`, t) of ``values`` (N, n, t) along the
        directions removed, in the order of :attr:`directions`."""
        fitted = np.tensordot(self.basis, values, axes=(0, 0))  # (c, n, t)
        return np.vstack(
            [
                fitted.transpose(1, 0, 2).reshape(fitted.shape[0] * fitted.shape[1], -1),
                np.tensordot(self.coupled, values, axes=([0, 1], [0, 1])),
            ]
        )

    def span(self, coefficients: np.ndarray) -> np.ndarray:
        """``Z c`` (N, n, t) for ``coefficients`` (:attr:`size`, t)."""
        ports = self.coupled.shape[1]
        fitted = self.basis.shape[1] * ports
        per_port = coefficients[:fitted].reshape(ports, self.basis.shape[1], -1)
        return np.tensordot(self.basis, per_port, axes=(1, 1)) + np.tensordot(
            self.coupled, coefficients[fitted:], axes=(2, 0)
        )

    @cached_property
    def directions(self) -> np.ndarray:
        """The orthonormal directions removed, (N, n, r): the fitted columns on every port
        (``c n`` of them, port by port) and the coupled ones kept (``r`` = :attr:`size`)."""
        samples, ports, _ = self.coupled.shape
        fitted = np.zeros((samples, ports, ports, self.basis.shape[1]))
        for port in range(ports):
            fitted[:, port, port] = self.basis
        return np.concatenate([fitted.reshape(samples, ports, -1), self.coupled], axis=2)


class Columns:
    """Columns (N, p, K) projected off the fitted directions, as the coordinates ``matrix``
    (M, K) of the projected columns in an orthonormal frame of M arrays (N, p) that holds
    them, with the ``norms`` (K,) of the columns before projection. This base class is the
    frame of every reading and port (M = N p): the projected columns themselves."""

    def __init__(self, projected: np.ndarray, norms: np.ndarray):
        self.shape = projected.shape[:2]
        self.matrix = projected.reshape(-1, projected.shape[2])
        self.norms = norms

    def coordinates(self, values: np.ndarray) -> np.ndarray:
        """Coordinates (M, t) of the part in the frame of ``values`` (N, p, t)."""
        return values.reshape(-1, values.shape[2])

    def vectors(self, coordinates: np.ndarray) -> np.ndarray:
        """The array (N, p) with ``coordinates`` (M,) in the frame."""
        return coordinates.reshape(self.shape)


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

    def __init__(self, direction: np.ndarray, fitted: np.ndarray, orders: int):
        self._factor_cosines(direction, orders)
        cross = self._inner(fitted)  # X'Z (K, r)
        inside = self._solve(cross)
        outside = fitted - self._span(inside)
        step = self._solve(self._inner(outside))
        outside -= self._span(step)
        self.frame, triangle = linalg.qr(
            outside.reshape(-1, outside.shape[2]), mode="economic", check_finite=False
        )
        self.matrix = np.vstack([self.factor.T - (inside + step) @ cross.T, -triangle @ cross.T])

    def _factor_cosines(self, direction: np.ndarray, orders: int) -> None:
        """The direction, and the Cholesky factor ``L`` and norms of the columns' Gram."""
        self.direction = direction
        self.shape = direction.shape
        weight = np.einsum("ij,ij->i", direction, direction)
        moments = _cosine_analysis(weight, 2 * orders + 1)
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
        rows = np.matmul(self.direction[:, None, :], values)[:, 0]
        return _cosine_analysis(rows, self.factor.shape[0] + 1)[1:]

    def _span(self, coefficients: np.ndarray) -> np.ndarray:
        """``U c`` for ``coefficients`` (K, t): (N, p, t)."""
        rows = _cosine_synthesis(self._solve(coefficients, transposed=True), self.shape[0])
        return self.direction[:, :, None] * rows[:, None, :]

    def coordinates(self, values: np.ndarray) -> np.ndarray:
        inside = self._solve(self._inner(values))
        return np.vstack([inside, self.frame.T @ values.reshape(-1, values.shape[2])])

    def vectors(self, coordinates: np.ndarray) -> np.ndarray:
        orders = self.factor.shape[0]
        outside = self.frame @ coordinates[orders:]
        return self._span(coordinates[:orders, None])[:, :, 0] + outside.reshape(self.shape)


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

    def __init__(self, direction: np.ndarray, projector: Projector, orders: int):
        self._factor_cosines(direction, orders)
        self.projector = projector
        ports = direction.shape[1]
        cross = np.hstack(  # X'Z (K, r), port by port: the basis on that port alone
            [
                _cosine_analysis(direction[:, port, None] * projector.basis, orders + 1)[1:]
                for port in range(ports)
            ]
            + [self._inner(projector.coupled)]
        )
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
        frame = self._off_frame(frame[:, sizes > RANK_TOLERANCE].reshape(self.shape + (-1,)))
        return linalg.qr(frame.reshape(rows, -1), mode="economic")[0]

    def _off_frame(self, values: np.ndarray) -> np.ndarray:
        """``values`` (N, n, t) less their parts along ``U`` and ``V``."""
        values = values - self._span(self._solve(self._inner(values)))
        return values - self._outside_vectors(self._outside_coordinates(values))

    def _outside_coordinates(self, values: np.ndarray) -> np.ndarray:
        """``V' v`` (s, t) of ``values`` (N, n, t)."""
        inside = self._solve(self._inner(values))
        along = self.rotation.T @ (self.projector.inner(values) - self.inside.T @ inside)
        return along / self.outside_norms[:, None]

    def _outside_vectors(self, coordinates: np.ndarray) -> np.ndarray:
        """``V c`` (N, n, t) for ``coordinates`` (s, t): ``(Z - U T) E diag(1/s) c``."""
        along = self.rotation @ (coordinates / self.outside_norms[:, None])
        return self.projector.span(along) - self._span(self.inside @ along)

    def coordinates(self, values: np.ndarray) -> np.ndarray:
        return np.vstack(
            [
                self._solve(self._inner(values)),
                self._outside_coordinates(values),
                self.frame.T @ values.reshape(-1, values.shape[2]),
            ]
        )

    def vectors(self, coordinates: np.ndarray) -> np.ndarray:
        orders, outside = self.factor.shape[0], self.outside_norms.size
        split = np.split(coordinates[:, None], [orders, orders + outside])
        along = self._outside_vectors(split[1])
        inside = self._span(split[0])
        formed = (self.frame @ split[2]).reshape(self.shape + (1,))
        return (inside + along + formed)[:, :, 0]


def projected_components(
    columns: np.ndarray, norms: np.ndarray, target: np.ndarray, tolerance: float = RANK_TOLERANCE
):
    """Nested projections of ``target`` (M, t) on ``columns`` (M, K) taken in order.

    Returns the mask of the columns kept (those not absorbed, to ``tolerance`` of their
    ``norms``, by the fitted directions and the columns kept before them), an orthonormal
    basis (M, kept) of the kept columns' nested spans (QR) and the components (K, t) of
    ``target`` on it, 0 for the columns not kept.
    """
    kept = np.ones(columns.shape[1], dtype=bool)
    while kept.any():
        frame, triangle = linalg.qr(columns[:, kept], mode="economic", check_finite=False)
        size = np.zeros(np.count_nonzero(kept))
        size[: min(triangle.shape)] = np.abs(np.diag(triangle))
        absorbed = size <= tolerance * np.maximum(norms[kept], np.finfo(float).tiny)
        if not absorbed.any():
            break
        # drop the first absorbed column only: those after it are judged without it
        kept[np.flatnonzero(kept)[np.argmax(absorbed)]] = False
    else:
        frame = np.zeros((columns.shape[0], 0))
    components = np.zeros((kept.size, target.shape[1]))
    components[kept] = frame.T @ target
    return kept, frame, components


@dataclass(frozen=True)
class ResidualTest:
    """A score test at its most significant scale."""

    p_value: float
    excess: float  # statistic minus degrees of freedom (whitened energy)
    orders: int  # functions of the row at this scale
    dof: int

    @property
    def failed(self) -> bool:
        return self.p_value < TEST_P_VALUE


class ResidualTests:
    """The score tests of the module docstring on one whitened residual (N, n)."""

    def __init__(self, residual, projector, residual_dof: float, rank_tolerance=RANK_TOLERANCE):
        self.rank_tolerance = rank_tolerance
        self.residual = projector(residual)
        self.projector = projector
        self.ports = residual.shape[1]
        self.total_dof = residual_dof * self.ports
        self.energy = float(np.einsum("ij,ij->", self.residual, self.residual))

    def p_values(self, statistic: np.ndarray, dof: np.ndarray) -> np.ndarray:
        """Upper tail of score statistics with ``dof`` degrees of freedom: the lack-of-fit
        F test against the rest of the whitened residual."""
        remaining = self.total_dof - dof
        # 1 where the columns leave no residual to compare with
        valid = (dof > 0) & (remaining >= 1.0)
        dof, remaining = np.where(valid, dof, 1), np.where(valid, remaining, 1.0)
        ratio = (statistic / dof) / np.maximum(self.energy - statistic, 1e-300) * remaining
        return np.where(valid, special.fdtrc(dof, remaining, ratio), 1.0)  # F(dof, remaining)

    def columns(self, basis: np.ndarray, direction: np.ndarray | None = None) -> Columns:
        """Columns ``basis_m(k)`` (N, K) on every port separately (``direction`` None) or
        times a per-reading image direction (N, n), projected off what the fit absorbs."""
        columns = (
            basis[:, None, :] if direction is None else basis[:, None, :] * direction[..., None]
        )
        projected = (
            self.projector.per_port(columns) if direction is None else self.projector(columns)
        )
        return Columns(projected, np.sqrt(np.einsum("ijk,ijk->k", columns, columns)))

    def cosines(self, orders: int, direction: np.ndarray | None = None) -> Columns:
        """:meth:`columns` of the first ``orders`` discrete cosines of the row: through DCTs
        (:class:`CosineColumns`), or formed for a sweep of fewer than ``MIN_DCT_READINGS``
        readings (faster there) or a ``direction`` too uneven (``MIN_GRAM_WEIGHT``)."""
        samples = self.residual.shape[0]
        unit = np.ones((samples, 1)) if direction is None else direction
        weight = np.einsum("ij,ij->i", unit, unit)
        if samples < MIN_DCT_READINGS or weight.min() < MIN_GRAM_WEIGHT * weight.max():
            return self.columns(_cosines(samples, orders), direction)
        if direction is None:
            return CosineColumns(unit, self.projector.basis[:, None], orders)
        if unit.size * self.projector.size > MAX_FORMED_DIRECTIONS:
            return ProjectedCosineColumns(unit, self.projector, orders)
        return CosineColumns(unit, self.projector.directions, orders)

    def coupled(
        self, columns: Columns, direction: np.ndarray, orders
    ) -> tuple[ResidualTest, np.ndarray]:
        """Columns ``basis_m(k) direction_k`` (:meth:`columns` with a direction), nested at
        ``orders``; also, per reading, the amplitude along ``direction`` of the residual these
        columns explain at the best order (what the fit did not absorb of the drift, in the
        unit of the direction's coefficient)."""
        target = columns.coordinates(self.residual[..., None])
        kept, frame, components = projected_components(
            columns.matrix, columns.norms, target, self.rank_tolerance
        )
        best = self._best(components[:, 0] ** 2, kept, orders)
        # the projection on the kept columns of the best order
        used = np.count_nonzero(kept[: best.orders])
        explained = columns.vectors(frame[:, :used] @ components[kept][:used, 0])
        return best, np.einsum("ij,ij->i", explained, direction) / np.einsum(
            "ij,ij->i", direction, direction
        )

    def per_port(self, columns: Columns, orders) -> tuple[ResidualTest, np.ndarray]:
        """Columns ``basis_m(k)`` (:meth:`columns` without a direction) on every port
        separately, nested at ``orders``; also each port's statistic at the largest order."""
        target = columns.coordinates(self.residual[:, None, :])
        kept, _, components = projected_components(
            columns.matrix, columns.norms, target, self.rank_tolerance
        )
        scores = components**2
        return self._best(scores.sum(axis=1), kept, orders, self.ports), scores.sum(axis=0)

    def _best(self, scores, kept, orders, ports: int = 1) -> ResidualTest:
        statistic = np.cumsum(scores)
        dof = np.cumsum(kept) * ports
        index = np.array(orders) - 1
        # the smallest p-value over the scales, times their number (Bonferroni)
        p_values = np.minimum(1.0, len(orders) * self.p_values(statistic[index], dof[index]))
        tests = [
            ResidualTest(float(p_value), float(statistic[k - 1] - dof[k - 1]), k, int(dof[k - 1]))
            for p_value, k in zip(p_values, orders, strict=True)
        ]
        return min(tests, key=lambda test: (test.p_value, -test.excess))
