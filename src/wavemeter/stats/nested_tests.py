"""Nested F tests of a whitened residual along columns the fit did not absorb.

After the fitted directions are projected out (:class:`~.projection.Projector`), the
whitened residual's energy along nested sets of columns (discrete cosines of the row index,
or other functions of the reading; on every channel alone or times a per-reading direction
that couples the channels) is a score statistic, tested by the lack-of-fit F test against
the rest of the residual (:class:`ResidualTests`); a family's p-value is its smallest over
the scales times their number (Bonferroni), and a test fails below ``TEST_P_VALUE``.
Cosine columns are factored through DCTs (:mod:`.cosine_columns`), or formed for short
series (``MIN_DCT_READINGS``) and per-reading directions too uneven for the cosines' Gram
matrix (``MIN_GRAM_WEIGHT``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, special

from .cosine_columns import CosineColumns, ProjectedCosineColumns
from .cosine_transform import discrete_cosines
from .projection import RANK_TOLERANCE, Columns

__all__ = [
    "TEST_P_VALUE",
    "MIN_GRAM_WEIGHT",
    "MIN_DCT_READINGS",
    "MAX_FORMED_DIRECTIONS",
    "projected_components",
    "ResidualTest",
    "ResidualTests",
]

#: false-alarm probability of each test for in-model data
TEST_P_VALUE = 1e-6
#: smallest squared norm of a reading's direction, relative to the largest, for which cosine
#: columns are orthonormalised through their Gram matrix (its condition number is at most
#: the inverse); below, they are formed and factored explicitly
MIN_GRAM_WEIGHT = 1e-6
#: fewest readings for which cosine columns are factored through DCTs (not formed)
MIN_DCT_READINGS = 128
#: most numbers (N n r) in the fitted directions formed for the tests coupling the ports
#: (134 MB); beyond, they are applied through their structure (:class:`ProjectedCosineColumns`)
MAX_FORMED_DIRECTIONS = 2**24


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

    def __init__(
        self, residual, projector, residual_dof: float, rank_tolerance=RANK_TOLERANCE, out=None
    ):
        self.rank_tolerance = rank_tolerance
        self.residual = projector(residual, out)  # into ``out`` (may be ``residual``)
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

    def columns(self, basis, direction: np.ndarray | None = None) -> Columns:
        """Columns ``basis_m(k)`` (N, K; or a function giving the rows of a slice of the
        readings) on every port separately (``direction`` None) or times a per-reading image
        direction (N, n), projected off what the fit absorbs."""
        target = self.residual[:, None, :] if direction is None else self.residual[..., None]
        return Columns(basis, direction, self.projector, target)

    def cosines(self, orders: int, direction: np.ndarray | None = None, weight=None) -> Columns:
        """:meth:`columns` of the first ``orders`` discrete cosines of the row: through DCTs
        (:class:`CosineColumns`), or formed for a sweep of fewer than ``MIN_DCT_READINGS``
        readings (faster there) or a ``direction`` too uneven (``MIN_GRAM_WEIGHT``);
        ``weight`` the direction's squared norm per reading, when known."""
        samples = self.residual.shape[0]
        if direction is not None and weight is None:
            weight = np.einsum("ij,ij->i", direction, direction)
        uneven = weight is not None and weight.min() < MIN_GRAM_WEIGHT * weight.max()
        if samples < MIN_DCT_READINGS or uneven:
            return self.columns(discrete_cosines(samples, orders), direction)
        if direction is None:
            return CosineColumns(None, self.projector.basis[:, None], orders)
        if direction.size * self.projector.size > MAX_FORMED_DIRECTIONS:
            return ProjectedCosineColumns(direction, self.projector, orders, weight)
        return CosineColumns(direction, self.projector.directions, orders, weight)

    def coupled(
        self, columns: Columns, direction: np.ndarray, orders, weight=None
    ) -> tuple[ResidualTest, np.ndarray]:
        """Columns ``basis_m(k) direction_k`` (:meth:`columns` with a direction), nested at
        ``orders``; also, per reading, the amplitude along ``direction`` of the residual these
        columns explain at the best order (what the fit did not absorb of the drift, in the
        unit of the direction's coefficient; ``weight`` its squared norm, when known)."""
        best, amplitude = self.coupled_test(columns, direction, orders, weight)
        return best, amplitude()

    def coupled_test(self, columns: Columns, direction: np.ndarray, orders, weight=None):
        """:meth:`coupled` with the amplitude as a function, evaluated when called."""
        target = columns.coordinates(self.residual[..., None])
        kept, frame, components = projected_components(
            columns.matrix, columns.norms, target, self.rank_tolerance
        )
        best = self._best(components[:, 0] ** 2, kept, orders)
        # the projection on the kept columns of the best order
        used = np.count_nonzero(kept[: best.orders])

        def amplitude() -> np.ndarray:
            squares = np.einsum("ij,ij->i", direction, direction) if weight is None else weight
            coordinates = frame[:, :used] @ components[kept][:used, 0]
            return columns.amplitude(coordinates, direction, squares)

        return best, amplitude

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
