"""The statistics of the fit diagnostics: model-free noise and nested cosine tests.

:mod:`wavemeter.calibration.checks.misfit` asks whether a calibration residual holds structure
that white noise would not: after the fit is projected out, the residual's energy along
nested sets of discrete cosines of the row index (smooth in time) or of the fringe phase
is tested against the model-free noise with F tests (:class:`ResidualTests`). The
model-free noise comes from second differences of the residual, corrected for the fit
(:func:`model_free_noise`).

The discrete cosines are never formed: their products with the readings are DCTs (they are
orthogonal, and the product of two is half the sum of two others), so the nested QR
factors of the cosine columns with the fit projected out come from matrices of ``K`` plus
the number of fitted directions in size, and a report costs ``O(N)`` per port and per test
instead of the ``O(N K^2)`` of a QR of ``N x K`` columns (:class:`CosineColumns`). Only the
first few hundred of the N cosine coefficients are needed: on long sweeps they come from
Taylor series over blocks of readings, a matrix product of ~14 terms per reading
(:func:`_cosine_analysis`, exact to rounding; 1e6 readings: 1.5 ms a column against 12 ms
for scipy's DCT). Short sweeps (``MIN_DCT_READINGS``) and per-reading directions too uneven
for the cosines' Gram matrix (``MIN_GRAM_WEIGHT``) form the columns instead, and so do the
tests of other functions of the reading (harmonics of the fringe phase, even polynomials
of the frequency): block by block, each factored by Householder QR beside the residual, the
blocks' triangles stacked (:class:`Columns`), so that no N x n x K array is held.

Every pass over the readings runs in blocks of ``ROW_BLOCK`` rows (:func:`row_blocks`),
whose temporaries stay in the cache: on 1e7 readings a temporary of the full length costs
more to map into memory than to compute.

What the fit absorbs (:class:`Projector`) is each port's fitted columns and one direction
per nonlinear parameter shared by the ports (the delay; a phase polynomial's coefficients).
For the tests that couple the ports these are ``r = c n + q`` arrays of N x n: formed while
they hold at most ``MAX_FORMED_DIRECTIONS`` numbers, applied through their structure beyond
(:class:`ProjectedCosineColumns`: for a wide-band map of 15 columns and 3 phase coefficients
on 5 ports and 176000 readings, a report takes 0.9 s and 0.3 GB so; 27 s and 2.5 GB
formed, as first measured with scipy's DCTs).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from scipy import fft, linalg, special
from scipy.linalg import lapack

__all__ = [
    "TEST_P_VALUE",
    "RANK_TOLERANCE",
    "MIN_GRAM_WEIGHT",
    "MIN_DCT_READINGS",
    "MAX_FORMED_DIRECTIONS",
    "MIN_OUTSIDE_GRAM",
    "MIN_TAYLOR_BLOCK",
    "TAYLOR_HALF_BLOCK_RAD",
    "TAYLOR_TRUNCATION",
    "ROW_BLOCK",
    "row_blocks",
    "orthonormal_columns",
    "inner_products",
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
#: fewest readings per block for which cosine coefficients are block Taylor series
#: (:func:`_cosine_analysis`); scipy's DCT is faster for shorter blocks
MIN_TAYLOR_BLOCK = 128
#: largest turn of a cosine from a block's centre to its ends (rad) in the Taylor series
TAYLOR_HALF_BLOCK_RAD = 0.25
#: relative size of the first Taylor term left out
TAYLOR_TRUNCATION = 2.0**-60
#: rows per block of the passes over the readings (temporaries of a few MB, in cache)
ROW_BLOCK = 2**15


_GEQRF, _ORGQR = lapack.dgeqrf, lapack.dorgqr


def row_blocks(samples: int):
    """Slices of ``ROW_BLOCK`` consecutive rows covering ``samples`` rows."""
    for start in range(0, samples, ROW_BLOCK):
        yield slice(start, min(start + ROW_BLOCK, samples))


def orthonormal_columns(columns: np.ndarray) -> np.ndarray:
    """Orthonormal basis (N, rank) of the span of ``columns`` (N, k), as
    :func:`scipy.linalg.orth` (the rank counts singular values above ``max(N, k)`` rounding
    units of the largest), from Householder QR and the SVD of its triangle: one copy of the
    columns in memory."""
    triangle, frame = _triangle(np.array(columns, dtype=float, order="F"), frame=True)
    left, singular, _ = linalg.svd(triangle, check_finite=False)
    tolerance = np.amax(singular, initial=0.0) * np.finfo(float).eps * max(columns.shape)
    rank = int(np.count_nonzero(singular > tolerance))
    for rows in row_blocks(frame.shape[0]):
        frame[rows, :rank] = frame[rows] @ left[:, :rank]
    return frame[:, :rank]


def inner_products(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """``left' right`` (a, b) of arrays (N, a) and (N, b), block by block."""
    total = np.zeros((left.shape[1], right.shape[1]))
    for rows in row_blocks(left.shape[0]):
        total += left[rows].T @ right[rows]
    return total


def _subtract_products(values, left, coefficients, out) -> np.ndarray:
    """``values - left @ coefficients`` ((N, b), ``left`` (N, a)) into ``out`` (which may be
    ``values``), block by block."""
    for rows in row_blocks(values.shape[0]):
        np.subtract(values[rows], left[rows] @ coefficients, out=out[rows])
    return out


def model_free_noise(residual: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, float]:
    """Second-difference noise per port (W) and its degrees of freedom.

    ``T = trace(D (I - H) D')`` and ``trace((D (I - H) D')^2)`` are computed from the band
    matrix ``D D'`` (6, -4, 1) and the low-rank ``U = D Q`` without forming N x N matrices:
    ``trace(U' D D' U) = 6 sum u_k^2 - 8 sum u_k u_(k+1) + 2 sum u_k u_(k+2)`` (rows ``u_k``
    of ``U``). One pass, block by block.
    """
    samples, ports = residual.shape
    rows = samples - 2  # rows of D
    squares = np.zeros(ports)
    gram = np.zeros((basis.shape[1],) * 2)
    lagged = np.zeros(3)  # sum u_k u_(k+s), s = 0, 1, 2
    for block in row_blocks(rows):
        differences = np.diff(residual[block.start : block.stop + 2], n=2, axis=0)
        squares += np.einsum("ij,ij->j", differences, differences)
        # rows of U from two before the block (the pairs ending in it)
        first = max(block.start - 2, 0)
        low_rank = np.diff(basis[first : block.stop + 2], n=2, axis=0)
        own = block.start - first
        gram += low_rank[own:].T @ low_rank[own:]
        for shift in (1, 2):
            start = max(own, shift)
            lagged[shift] += np.einsum(
                "ij,ij->", low_rank[start:], low_rank[start - shift : -shift]
            )
    lagged[0] = np.trace(gram)
    trace = 6.0 * rows - lagged[0]
    band = 36.0 * rows + 32.0 * max(samples - 3, 0) + 2.0 * max(samples - 4, 0)
    spread = 6.0 * lagged[0] - 8.0 * lagged[1] + 2.0 * lagged[2]
    trace_square = band - 2.0 * spread + np.sum(gram**2)
    return np.sqrt(squares / trace), float(trace**2 / trace_square)


def _cosines(samples: int, orders: int) -> np.ndarray:
    """The first ``orders`` discrete cosines ``cos(pi m (k + 1/2) / N)``, m = 1.. (N, K)."""
    index = np.arange(samples) + 0.5
    return np.cos(np.pi * np.outer(index, np.arange(1, orders + 1)) / samples)


def _taylor_block(samples: int, orders: int) -> int:
    """Readings per block of the Taylor transform: the largest power of two over which no
    cosine of order below ``orders`` turns by more than ``TAYLOR_HALF_BLOCK_RAD`` from the
    block's centre (1 when none fits)."""
    top = max(orders - 1, 1)
    block = 1
    while 2 * block <= samples and np.pi * top * block <= TAYLOR_HALF_BLOCK_RAD * samples:
        block *= 2
    return block


@dataclass(frozen=True)
class _TaylorPlan:
    """Tables of the block Taylor transform of ``samples`` readings and ``orders`` cosines
    (:func:`_cosine_analysis`): with ``L`` readings per block, reading ``j`` of block ``b``
    has the phase ``pi m (k + 1/2) / N = phi_mb + a_m x_j`` (``phi_mb`` at the block's
    centre, ``a_m = pi m L / N``, ``x_j`` in (-1/2, 1/2)), and ``cos(phi + a x) = sum_p
    (a x)^p / p! cos^(p)(phi)``."""

    samples: int
    block: int  # L, a power of two: x_j exact
    cos: np.ndarray  # (M, B): cos phi_mb
    sin: np.ndarray  # (M, B)
    powers: np.ndarray  # (L, P): x_j^p / p!
    along_cos: np.ndarray  # (M, P): a_m^p times the sign of cos in cos^(p) (0 for p odd)
    along_sin: np.ndarray  # (M, P): a_m^p times the sign of sin in cos^(p) (0 for p even)

    @property
    def full_blocks(self) -> int:
        return self.samples // self.block

    def moments(self, values: np.ndarray) -> np.ndarray:
        """``sum_j v_(bL + j) x_j^p / p!`` (t, B, P) of ``values`` (N, t)."""
        full, tail = self.full_blocks, self.samples % self.block
        moments = np.empty((values.shape[1], self.cos.shape[1], self.powers.shape[1]))
        for column, out in zip(values.T, moments, strict=True):
            column = np.ascontiguousarray(column)
            np.matmul(column[: full * self.block].reshape(full, -1), self.powers, out=out[:full])
            if tail:
                out[full] = column[full * self.block :] @ self.powers[:tail]
        return moments

    def values(self, weights: np.ndarray) -> np.ndarray:
        """``sum_p x_j^p / p! w_(bp)`` (N, t), Fortran order, for block weights (B, P, t)."""
        full, tail = self.full_blocks, self.samples % self.block
        values = np.empty((weights.shape[2], self.samples))
        for column, index in zip(values, range(weights.shape[2]), strict=True):
            blocks = column[: full * self.block].reshape(full, -1)
            np.matmul(weights[:full, :, index], self.powers.T, out=blocks)
            if tail:
                column[full * self.block :] = self.powers[:tail] @ weights[full, :, index]
        return values.T


@lru_cache(maxsize=4)
def _taylor_plan(samples: int, orders: int) -> _TaylorPlan:
    block = _taylor_block(samples, orders)
    blocks = -(-samples // block)
    # phi_mb = pi m (2 k_b + L) / (2 N), reduced exactly in integers to [0, 2 pi)
    order = np.arange(orders)
    turns = np.outer(order, 2 * block * np.arange(blocks) + block) % (4 * samples)
    phase = turns * (np.pi / (2 * samples))
    half_turn = np.pi * (orders - 1) * block / (2 * samples)  # largest |a_m x_j|
    terms = 1
    while half_turn**terms / special.factorial(terms) > TAYLOR_TRUNCATION:
        terms += 1
    degree = np.arange(terms)
    offsets = (2.0 * np.arange(block) + 1.0 - block) / (2.0 * block)
    powers = offsets[:, None] ** degree / special.factorial(degree)
    along = (np.pi * block / samples * order)[:, None] ** degree
    # d^p/dphi^p cos phi: cos, -sin, -cos, sin, ...
    cos_sign = np.where(degree % 2 == 0, 1.0 - (degree % 4), 0.0)
    sin_sign = np.where(degree % 2 == 1, (degree % 4) - 2.0, 0.0)
    return _TaylorPlan(
        samples, block, np.cos(phase), np.sin(phase), powers, along * cos_sign, along * sin_sign
    )


def _cosine_analysis(values: np.ndarray, orders: int) -> np.ndarray:
    """``sum_k b_m(k) v_k`` for ``m = 0..orders - 1`` (DCT-II): (N, ...) -> (orders, ...).

    Block Taylor series (:class:`_TaylorPlan`, ``O(N P)`` with ``P`` ~ 14 terms, a matrix
    product) when the blocks hold ``MIN_TAYLOR_BLOCK`` readings or more, else scipy's DCT
    (``O(N log N)``, all ``N`` coefficients); both exact to rounding.
    """
    samples = values.shape[0]
    if _taylor_block(samples, orders) < MIN_TAYLOR_BLOCK:
        return fft.dct(values, type=2, axis=0)[:orders] / 2.0
    plan = _taylor_plan(samples, orders)
    moments = plan.moments(values.reshape(samples, -1))
    coefficients = np.einsum("tmp,mp->mt", plan.cos @ moments, plan.along_cos) + np.einsum(
        "tmp,mp->mt", plan.sin @ moments, plan.along_sin
    )
    return coefficients.reshape((orders,) + values.shape[1:])


def _cosine_synthesis(coefficients: np.ndarray, samples: int) -> np.ndarray:
    """``sum_m c_m b_m(k)`` for ``m = 1..K`` (DCT-III): (K, ...) -> (N, ...), by block
    Taylor series or scipy's DCT as :func:`_cosine_analysis`."""
    orders = coefficients.shape[0] + 1
    if _taylor_block(samples, orders) < MIN_TAYLOR_BLOCK:
        padded = np.zeros((samples, coefficients[0].size), order="F")
        padded[1:orders] = coefficients.reshape(orders - 1, -1) / 2.0
        return fft.dct(padded, type=3, axis=0).reshape((samples,) + coefficients.shape[1:])
    plan = _taylor_plan(samples, orders)
    flat = coefficients.reshape(orders - 1, -1)
    weights = np.tensordot(plan.cos[1:], plan.along_cos[1:, :, None] * flat[:, None], (0, 0))
    weights += np.tensordot(plan.sin[1:], plan.along_sin[1:, :, None] * flat[:, None], (0, 0))
    return plan.values(weights).reshape((samples,) + coefficients.shape[1:], order="F")


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
                column /= remaining
                kept.append(column)
        if len(kept) == 1:
            self.coupled = kept[0][:, :, None]
        else:
            self.coupled = np.stack(kept, axis=2) if kept else np.zeros(coupled.shape[:2] + (0,))
        # B' coupled_j per port j (n, c, q): ~0, the coupled directions are off the basis
        samples, ports, kept_count = self.coupled.shape
        products = inner_products(basis, self.coupled.reshape(samples, -1))
        self.basis_coupled = products.reshape(-1, ports, kept_count).transpose(1, 0, 2)

    def per_port(self, values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``values`` (N, ...) less their projection on the fitted columns, into ``out``
        (contiguous, may be ``values``) or a new array."""
        flat = values.reshape(values.shape[0], -1)
        result = np.empty(flat.shape) if out is None else out.reshape(flat.shape)
        _subtract_products(flat, self.basis, inner_products(self.basis, flat), result)
        return result.reshape(values.shape)

    def __call__(self, values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``values`` (N, n, ...) off every direction removed, into ``out`` or a new array."""
        projected = self.per_port(values, out)
        rows = projected.shape[0] * projected.shape[1]
        flat = projected.reshape(rows, -1)
        coupled = self.coupled.reshape(rows, -1)
        _subtract_products(flat, coupled, inner_products(coupled, flat), flat)
        return projected

    @property
    def size(self) -> int:
        """Number of directions removed: ``c n`` fitted columns and the coupled ones kept."""
        return self.basis.shape[1] * self.coupled.shape[1] + self.coupled.shape[2]

    def inner(self, values: np.ndarray) -> np.ndarray:
        """Coordinates ``Z' v`` (:attr:`size`, t) of ``values`` (N, n, t) along the
        directions removed, in the order of :attr:`directions`."""
        samples, ports, _ = values.shape
        fitted = inner_products(self.basis, values.reshape(samples, -1))  # (c, n t)
        fitted = fitted.reshape(fitted.shape[0], ports, -1)
        coupled = self.coupled.reshape(samples * ports, -1)
        return np.vstack(
            [
                fitted.transpose(1, 0, 2).reshape(fitted.shape[0] * ports, -1),
                inner_products(coupled, values.reshape(samples * ports, -1)),
            ]
        )

    def span(self, coefficients: np.ndarray) -> np.ndarray:
        """``Z c`` (N, n, t) for ``coefficients`` (:attr:`size`, t)."""
        samples, ports, _ = self.coupled.shape
        vectors = np.empty((samples, ports, coefficients.shape[1]))
        for rows, block in self._span_blocks(coefficients):
            vectors[rows] = block
        return vectors

    def span_along(self, coefficients: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """``(Z c)_k D_k`` (N,) for ``coefficients`` (:attr:`size`,) and a per-reading
        direction ``D`` (N, n), without forming ``Z c``."""
        along = np.empty(direction.shape[0])
        for rows, block in self._span_blocks(coefficients[:, None]):
            along[rows] = np.einsum("ij,ij->i", block[:, :, 0], direction[rows])
        return along

    def _span_blocks(self, coefficients: np.ndarray):
        """``Z c`` block by block: (rows, (L, n, t))."""
        samples, ports, _ = self.coupled.shape
        columns = self.basis.shape[1]
        per_port = coefficients[: columns * ports].reshape(ports, columns, -1)
        per_port = per_port.transpose(1, 0, 2).reshape(columns, -1)  # (c, n t)
        along = coefficients[columns * ports :]
        for rows in row_blocks(samples):
            block = (self.basis[rows] @ per_port).reshape(-1, ports, coefficients.shape[1])
            block += np.tensordot(self.coupled[rows], along, axes=(2, 0))
            yield rows, block

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
    them and a target (N, p, t), with the ``norms`` (K,) of the columns before projection.

    This base class forms the columns ``f_m(k) D_k`` (``f`` (N, K) functions of the reading,
    given as an array or as a function of a slice of the readings returning its rows; ``D``
    (N, n) a per-reading direction, or None: ``f`` on every port separately, p = 1)
    block by block, projects them (:class:`Projector`: per port, or off every direction
    with ``D``) and factors each block beside the target by Householder QR, ``[Y_b, R_b] =
    Q_b S_b`` (TSQR): the frame is the blocks' ``Q_b`` (M = the sum of the ``S_b`` rows),
    the columns' coordinates ``S[:, :K]`` and the target's ``S[:, K:]``; no array of the
    N p K numbers is formed.
    """

    def __init__(self, functions, direction, projector: Projector, target):
        self.functions = functions if callable(functions) else functions.__getitem__
        self.direction, self.projector = direction, projector
        self.shape = target.shape[:2]
        self._target = target
        orders, ports = self.functions(slice(0, 0)).shape[1], self.shape[1]
        basis, coupled = projector.basis, projector.coupled
        squares = np.zeros(orders)
        per_port = np.zeros((orders, basis.shape[1], ports))
        along = np.zeros((coupled.shape[2], orders))
        for rows in row_blocks(self.shape[0]):
            columns = self._formed(rows, orders)
            squares += np.einsum("ij,ij->j", columns, columns)
            per_port += basis[rows].T @ columns.T.reshape(orders, -1, ports)
            if direction is not None:
                along += coupled[rows].reshape(-1, coupled.shape[2]).T @ columns
        self.norms = np.sqrt(squares)
        self._per_port = per_port  # B'X (K, c, p)
        if direction is not None:
            # coupled'(X - B C) = coupled'X - sum_j (B' coupled_j)' C_j: the coupled part of
            # the columns left after the per-port projection
            along -= np.einsum("jaq,kaj->qk", projector.basis_coupled, per_port)
        self._along = along
        factors = [_triangle(self._augmented(rows))[0] for rows in row_blocks(self.shape[0])]
        self._sizes = [factor.shape[0] for factor in factors]
        stacked = np.vstack(factors)
        self.matrix, self._coordinates = stacked[:, :orders], stacked[:, orders:]

    def _formed(self, rows: slice, width: int) -> np.ndarray:
        """(L p, ``width``), Fortran order, its first K columns those of readings ``rows``
        (row ``k p + j`` reading ``k``, port ``j``)."""
        functions = self.functions(rows)
        formed = np.empty((functions.shape[0] * self.shape[1], width), order="F")
        if self.direction is None:
            formed[:, : functions.shape[1]] = functions
            return formed
        direction = self.direction[rows]
        for order in range(functions.shape[1]):
            column = formed[:, order].reshape(direction.shape)
            np.multiply(direction, functions[:, order, None], out=column)
        return formed

    def _augmented(self, rows: slice) -> np.ndarray:
        """``[Y_b, R_b]`` (L p, K + t), Fortran order: the projected columns and the target
        of readings ``rows``."""
        basis, coupled = self.projector.basis, self.projector.coupled
        orders = self._per_port.shape[0]
        augmented = self._formed(rows, orders + self._target.shape[2])
        projected = augmented[:, :orders]
        # (K, L, p) and (K, L p) products: their transposes have the columns' layout
        projected -= (basis[rows] @ self._per_port).reshape(orders, -1).T
        if self.direction is not None:
            projected -= (self._along.T @ coupled[rows].reshape(-1, coupled.shape[2]).T).T
        augmented[:, orders:] = self._target[rows].reshape(projected.shape[0], -1)
        return augmented

    def coordinates(self, values: np.ndarray) -> np.ndarray:
        """Coordinates (M, t) of ``values`` (N, p, t): the target the columns were factored
        with (these columns take no other)."""
        return self._coordinates

    def amplitude(self, coordinates: np.ndarray, direction: np.ndarray, weight) -> np.ndarray:
        """``v_k D_k / w_k`` (N,) of the array ``v`` (N, p) with ``coordinates`` (M,) in the
        frame, for a direction ``D`` (N, p) of squared norms ``w`` (N,); each block's
        ``Q_b`` from its factorisation again."""
        amplitude = np.empty(self.shape[0])
        parts = np.split(coordinates, np.cumsum(self._sizes)[:-1])
        for rows, part in zip(row_blocks(self.shape[0]), parts, strict=True):
            vectors = (_triangle(self._augmented(rows), frame=True)[1] @ part).reshape(
                -1, self.shape[1]
            )
            amplitude[rows] = np.einsum("ij,ij->i", vectors, direction[rows]) / weight[rows]
        return amplitude


def _triangle(matrix: np.ndarray, frame: bool = False):
    """Householder QR of ``matrix`` (m, k), Fortran order, overwritten (LAPACK ``geqrf``):
    the triangle (min(m, k), k) and, with ``frame``, the orthonormal (m, min(m, k))."""
    size = min(matrix.shape)
    factored, tau, _, info = _GEQRF(matrix, lwork=64 * matrix.shape[1], overwrite_a=True)
    if info != 0:
        raise linalg.LinAlgError(f"geqrf failed (info {info})")
    triangle = np.triu(factored[:size])
    if not frame:
        return triangle, None
    orthonormal, _, info = _ORGQR(factored[:, :size], tau[:size], lwork=64 * size, overwrite_a=True)
    if info != 0:
        raise linalg.LinAlgError(f"orgqr failed (info {info})")
    return triangle, orthonormal


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
        triangle, self.frame = _triangle(outside.reshape(-1, outside.shape[2]), frame=True)
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
        if self.direction is None:
            rows = values[:, 0, :]
        else:  # each column's readings contiguous (the transform runs down the readings)
            rows = np.einsum("kp,kpt->tk", self.direction, values).T
        return _cosine_analysis(rows, self.factor.shape[0] + 1)[1:]

    def _span(self, coefficients: np.ndarray) -> np.ndarray:
        """``U c`` for ``coefficients`` (K, t): (N, p, t), the readings and ports of each
        column contiguous (Fortran order in (N p, t))."""
        rows = _cosine_synthesis(self._solve(coefficients, transposed=True), self.shape[0])
        if self.direction is None:
            return rows[:, None, :]
        vectors = np.empty((coefficients.shape[1],) + self.shape).transpose(1, 2, 0)
        return np.multiply(self.direction[:, :, None], rows[:, None, :], out=vectors)

    def coordinates(self, values: np.ndarray) -> np.ndarray:
        inside = self._solve(self._inner(values))
        return np.vstack([inside, inner_products(self.frame, values.reshape(-1, values.shape[2]))])

    def _along(self, coefficients: np.ndarray) -> np.ndarray:
        """``(U c)_k D_k / w_k`` (N,) for ``coefficients`` (K,): the cosine sum itself."""
        return _cosine_synthesis(
            self._solve(coefficients[:, None], transposed=True), self.shape[0]
        )[:, 0]

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
            cross.append(_cosine_analysis(products.T, orders + 1)[1:])
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
        frame = self._off_frame(frame[:, sizes > RANK_TOLERANCE].reshape(self.shape + (-1,)))
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
            return self.columns(_cosines(samples, orders), direction)
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
