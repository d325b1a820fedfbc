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
test instead of the ``O(N K^2)`` of a QR of ``N x K`` columns (``_CosineColumns``). Short
sweeps (``MIN_DCT_READINGS``) and per-reading directions too uneven for the cosines' Gram
matrix (``MIN_GRAM_WEIGHT``) form the columns instead.
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
    "model_free_noise",
    "Projector",
    "Columns",
    "CosineColumns",
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
    columns (orthonormal ``basis``, N x c) and the delay (one direction coupling the ports)."""

    def __init__(self, basis: np.ndarray, delay_column: np.ndarray):
        self.basis = basis
        delay = self.per_port(delay_column)
        norm = np.sqrt(np.einsum("ij,ij->", delay, delay))
        self.delay = delay / norm if norm > 0 else delay

    def per_port(self, values: np.ndarray) -> np.ndarray:
        return values - np.tensordot(
            self.basis, np.tensordot(self.basis, values, axes=(0, 0)), axes=(1, 0)
        )

    def __call__(self, values: np.ndarray) -> np.ndarray:
        projected = self.per_port(values)
        along = np.tensordot(self.delay, projected, axes=([0, 1], [0, 1]))
        return projected - np.multiply.outer(self.delay, along)

    @cached_property
    def directions(self) -> np.ndarray:
        """The orthonormal directions removed, (N, n, r): the fitted columns on every port
        (``c n`` of them) and the delay, unless it is absorbed (``r = c n + 1`` or ``c n``)."""
        samples, ports = self.delay.shape
        fitted = np.zeros((samples, ports, ports, self.basis.shape[1]))
        for port in range(ports):
            fitted[:, port, port] = self.basis
        fitted = fitted.reshape(samples, ports, -1)
        if not self.delay.any():
            return fitted
        return np.concatenate([fitted, self.delay[:, :, None]], axis=2)


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
        self.direction = direction
        self.shape = direction.shape
        weight = np.einsum("ij,ij->i", direction, direction)
        moments = _cosine_analysis(weight, 2 * orders + 1)
        index = np.arange(1, orders + 1)
        gram = 0.5 * (moments[np.abs(index[:, None] - index)] + moments[index[:, None] + index])
        self.factor = linalg.cholesky(gram, lower=True, check_finite=False)
        self.norms = np.sqrt(np.diag(gram))
        cross = self._inner(fitted)  # X'Z (K, r)
        inside = self._solve(cross)
        outside = fitted - self._span(inside)
        step = self._solve(self._inner(outside))
        outside -= self._span(step)
        self.frame, triangle = linalg.qr(
            outside.reshape(-1, outside.shape[2]), mode="economic", check_finite=False
        )
        self.matrix = np.vstack([self.factor.T - (inside + step) @ cross.T, -triangle @ cross.T])

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
        fitted = self.projector.basis[:, None] if direction is None else self.projector.directions
        return CosineColumns(unit, fitted, orders)

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
