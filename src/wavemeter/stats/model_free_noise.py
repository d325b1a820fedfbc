"""The noise of a residual without its model: second differences along the rows.

Each channel's noise ``s_j`` comes from the second differences of its residual along the
rows, ``e_k = r_{k+1} - 2 r_k + r_{k-1}``, corrected for the fitted columns: ``s_j^2 = sum
e^2 / T`` with ``T = trace(D (I - H) D')`` (``D`` the second-difference operator, ``H`` the
projector on the fitted columns), unbiased for white noise after the fit, on ``T^2 /
trace((D (I - H) D')^2)`` degrees of freedom (Satterthwaite). A misfit that changes slowly
from reading to reading is suppressed by the double difference.
"""

from __future__ import annotations

import numpy as np

from .blocks import row_blocks

__all__ = ["model_free_noise"]


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
