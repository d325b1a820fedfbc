"""Fits run BLAS and LAPACK on one thread, and give the threads back after."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from threadpoolctl import ThreadpoolController

import wavemeter as wm

FSR_HZ = 50e9
#: the linear algebra a learned fit calls (least squares, QR and Cholesky factors, triangular
#: solves, pseudo-inverses): each call's BLAS threads are recorded
LAPACK_CALLS = [
    (scipy.linalg, "lstsq"),
    (scipy.linalg, "qr"),
    (scipy.linalg, "cholesky"),
    (scipy.linalg, "solve_triangular"),
    (scipy.linalg, "pinv"),
    (np.linalg, "pinv"),
]


def blas_threads() -> set[int]:
    libraries = ThreadpoolController().select(user_api="blas").lib_controllers
    return {library.num_threads for library in libraries}


@pytest.fixture
def sweep():
    device = wm.Interferometer.table1(3, seed=4)
    frequency_hz = device.sweep_hz(400)
    return frequency_hz, device.powers(frequency_hz, 1e-3, 5e-7, np.random.default_rng(4))


@pytest.mark.parametrize("entry", ["fit", "fit_chunks"])
def test_a_fit_runs_blas_on_one_thread_and_restores_it(monkeypatch, sweep, entry):
    frequency_hz, powers = sweep
    seen = []

    def recorded(function):
        def record(*args, **kwargs):
            seen.append(blas_threads())
            return function(*args, **kwargs)

        return record

    # the fit's LAPACK calls, each looked up on its module when called
    for module, name in LAPACK_CALLS:
        monkeypatch.setattr(module, name, recorded(getattr(module, name)))
    with ThreadpoolController().limit(limits=2, user_api="blas"):
        outside = blas_threads()
        if outside == {1}:
            pytest.skip("BLAS cannot run on more than one thread here")
        cal = wm.Calibrator(FSR_HZ)
        if entry == "fit":
            cal.fit(powers, frequency_hz)
        else:
            cal.fit_chunks([(frequency_hz, powers, None)])
        after = blas_threads()
    assert seen and all(threads == {1} for threads in seen)
    assert after == outside
