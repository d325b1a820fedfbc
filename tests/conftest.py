"""Fixtures shared by the test files: seeded randomness; the suite's one BLAS thread; the
hypothesis profiles (the default run draws the same examples every run).

Importable helpers and constants live in ``tests/helpers.py``, not here.
"""

from __future__ import annotations

import os

# the suite's arrays are small: one BLAS thread per process avoids oversubscribing the
# 2-core machines, where threaded OpenBLAS makes small factorisations 10-100x slower
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

from .helpers import DEFAULT_PROFILE, FUZZ_PROFILE  # noqa: E402

# the default run's property tests: the same examples on every run and machine (drawn from
# each test's own source, not a clock), no example database carrying a failure from one run
# to the next, and no check that depends on timing (a deadline, the too-slow health check);
# ``make fuzz``: new examples from the seed it prints (``--hypothesis-seed``), still without
# a database: a failure is repeated with ``make fuzz FUZZ_SEED=<seed>``
settings.register_profile(
    DEFAULT_PROFILE,
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    FUZZ_PROFILE,
    derandomize=False,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
# `--hypothesis-profile` (make fuzz) loads its profile after this module
settings.load_profile(DEFAULT_PROFILE)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)
