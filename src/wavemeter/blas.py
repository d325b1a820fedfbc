"""BLAS and LAPACK on one thread for the fits, whose matrices are tall and thin.

A fit factors and multiplies matrices of many rows and a few columns (the QR factors of the
residual tests, the moments' products). OpenBLAS shares such a call among threads that then
spin, waiting for the next one, and take the cores from the work itself: a
``Calibrator.fit`` of 1e6 readings took 0.75 s with OpenBLAS's default threads and 0.34 s on
one, on this project's 2-core machine (the command line sets ``OPENBLAS_NUM_THREADS=1`` when
it starts; a library user's process has the default). threadpoolctl sets the threads of the
BLAS libraries loaded for the duration of a call and restores them after.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator

__all__ = ["one_blas_thread"]


@functools.cache
def _controller():
    """The BLAS libraries loaded (numpy's, scipy's) when the first fit runs."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """BLAS and LAPACK calls on the calling thread alone while the block runs (13 us to
    enter and leave); the threads they had are restored after."""
    with _controller().limit(limits=1, user_api="blas"):
        yield
