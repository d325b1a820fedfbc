"""Projection off what a fit absorbs, and test columns projected and factored in blocks.

What a fit of a residual (N readings, n channels) absorbs (:class:`Projector`) is each
channel's fitted columns (one orthonormal basis shared by the channels) and one direction
per nonlinear parameter shared by the channels (the delay; a phase polynomial's
coefficients): these couple the channels. Columns to test against the residual
(:class:`Columns`: functions of the reading, on each channel alone or times a per-reading
direction) are formed block by block, projected off what the fit absorbs, and factored by
Householder QR beside the residual, the blocks' triangles stacked (TSQR), so that no
N x n x K array is held.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from .blocks import householder_qr, inner_products, row_blocks, subtract_products

__all__ = ["RANK_TOLERANCE", "Projector", "Columns"]

#: relative size under which a projected column counts as absorbed by the fit
RANK_TOLERANCE = 1e-8


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
        self.coupled = _orthonormalised(projected, norms)
        # B' coupled_j per port j (n, c, q): ~0, the coupled directions are off the basis
        samples, ports, kept_count = self.coupled.shape
        products = inner_products(basis, self.coupled.reshape(samples, -1))
        self.basis_coupled = products.reshape(basis.shape[1], ports, kept_count).transpose(1, 0, 2)

    def per_port(self, values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``values`` (N, ...) less their projection on the fitted columns, into ``out``
        (contiguous, may be ``values``) or a new array."""
        flat = values.reshape(values.shape[0], -1)
        result = np.empty(flat.shape) if out is None else out.reshape(flat.shape)
        subtract_products(flat, self.basis, inner_products(self.basis, flat), result)
        return result.reshape(values.shape)

    def __call__(self, values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``values`` (N, n, ...) off every direction removed, into ``out`` or a new array."""
        projected = self.per_port(values, out)
        rows = projected.shape[0] * projected.shape[1]
        flat = projected.reshape(rows, -1)
        coupled = self.coupled.reshape(rows, -1)
        subtract_products(flat, coupled, inner_products(coupled, flat), flat)
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
            block = (self.basis[rows] @ per_port).reshape(
                rows.stop - rows.start, ports, coefficients.shape[1]
            )
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


def _orthonormalised(projected: np.ndarray, norms: np.ndarray) -> np.ndarray:
    """The columns ``projected`` (N, n, q) orthonormalised in order (Gram-Schmidt's result,
    signs kept), each one the ones before absorb (to ``RANK_TOLERANCE`` of its ``norms``)
    dropped: by Householder QR of the columns up to the first dropped one, the rest
    projected off what was kept (twice) and factored again."""
    samples, ports, _ = projected.shape
    columns = np.array(projected.reshape(samples * ports, -1), order="F")
    frames = []
    while columns.shape[1]:
        for _ in range(2):
            for frame in frames:
                columns -= frame @ (frame.T @ columns)
        triangle, frame = householder_qr(np.array(columns, order="F"), frame=True)
        diagonal = np.diag(triangle)[: columns.shape[1]]
        absorbed = np.abs(diagonal) <= RANK_TOLERANCE * norms[: diagonal.size]
        first = int(np.argmax(absorbed)) if absorbed.any() else diagonal.size
        frames.append(frame[:, :first] * np.sign(diagonal[:first]))
        columns, norms = columns[:, first + 1 :], norms[first + 1 :]
    kept = np.hstack(frames) if frames else np.zeros((samples * ports, 0))
    return kept.reshape(samples, ports, -1)


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
        factors = [householder_qr(self._augmented(rows))[0] for rows in row_blocks(self.shape[0])]
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
            vectors = (householder_qr(self._augmented(rows), frame=True)[1] @ part).reshape(
                -1, self.shape[1]
            )
            amplitude[rows] = np.einsum("ij,ij->i", vectors, direction[rows]) / weight[rows]
        return amplitude
