"""Fixtures shared by the test files: seeded randomness; the suite's one BLAS thread.

Importable helpers and constants live in ``tests/helpers.py``, not here.
"""

from __future__ import annotations

import os

# the suite's arrays are small: one BLAS thread per process avoids oversubscribing the
# 2-core machines, where threaded OpenBLAS makes small factorisations 10-100x slower
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)
