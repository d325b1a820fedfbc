"""Passes over tall arrays in blocks of rows: products, Householder QR, orthonormal bases.

Every pass over the readings runs in blocks of ``ROW_BLOCK`` rows (:func:`row_blocks`),
whose temporaries stay in the cache: on 1e7 readings a temporary of the full length costs
more to map into memory than to compute. :func:`householder_qr` factors a block (LAPACK
``geqrf``, its frame from ``orgqr`` when asked), and :func:`orthonormal_columns` gives the
span of tall columns as :func:`scipy.linalg.orth` does with one copy of them in memory.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg
from scipy.linalg import lapack

__all__ = [
    "ROW_BLOCK",
    "row_blocks",
    "inner_products",
    "subtract_products",
    "householder_qr",
    "orthonormal_columns",
]

#: rows per block of the passes over the readings (temporaries of a few MB, in cache)
ROW_BLOCK = 2**15


_GEQRF, _ORGQR = lapack.dgeqrf, lapack.dorgqr


def row_blocks(samples: int):
    """Slices of ``ROW_BLOCK`` consecutive rows covering ``samples`` rows."""
    for start in range(0, samples, ROW_BLOCK):
        yield slice(start, min(start + ROW_BLOCK, samples))


def inner_products(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """``left' right`` (a, b) of arrays (N, a) and (N, b), block by block."""
    total = np.zeros((left.shape[1], right.shape[1]))
    for rows in row_blocks(left.shape[0]):
        total += left[rows].T @ right[rows]
    return total


def subtract_products(values, left, coefficients, out) -> np.ndarray:
    """``values - left @ coefficients`` ((N, b), ``left`` (N, a)) into ``out`` (which may be
    ``values``), block by block."""
    for rows in row_blocks(values.shape[0]):
        np.subtract(values[rows], left[rows] @ coefficients, out=out[rows])
    return out


def householder_qr(matrix: np.ndarray, frame: bool = False):
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


def orthonormal_columns(columns: np.ndarray) -> np.ndarray:
    """Orthonormal basis (N, rank) of the span of ``columns`` (N, k), as
    :func:`scipy.linalg.orth` (the rank counts singular values above ``max(N, k)`` rounding
    units of the largest), from Householder QR and the SVD of its triangle: one copy of the
    columns in memory."""
    triangle, frame = householder_qr(np.array(columns, dtype=float, order="F"), frame=True)
    left, singular, _ = linalg.svd(triangle, check_finite=False)
    tolerance = np.amax(singular, initial=0.0) * np.finfo(float).eps * max(columns.shape)
    rank = int(np.count_nonzero(singular > tolerance))
    for rows in row_blocks(frame.shape[0]):
        frame[rows, :rank] = frame[rows] @ left[:, :rank]
    return frame[:, :rank]
