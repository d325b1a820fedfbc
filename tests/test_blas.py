"""Fits run BLAS and LAPACK on one thread, and give the threads back after."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import ThreadpoolController

import wavemeter as wm
from wavemeter.calibration.methods.learned import Calibrator

FSR_HZ = 50e9


def blas_threads() -> set[int]:
    libraries = ThreadpoolController().select(user_api="blas").lib_controllers
    return {library.num_threads for library in libraries}


@pytest.fixture
def sweep():
    device = wm.Interferometer.table1(3, seed=4)
    frequency_hz = device.sweep_hz(3000)
    return frequency_hz, device.powers(frequency_hz, 1e-3, 5e-7, np.random.default_rng(4))


@pytest.mark.parametrize("entry", ["fit", "fit_chunks"])
def test_a_fit_runs_blas_on_one_thread_and_restores_it(monkeypatch, sweep, entry):
    frequency_hz, powers = sweep
    seen = []
    accumulate, fit_sweep = Calibrator._accumulate, Calibrator._fit_sweep

    def recorded(method):
        def record(self, *args):
            seen.append(blas_threads())
            return method(self, *args)

        return record

    monkeypatch.setattr(Calibrator, "_accumulate", recorded(accumulate))
    monkeypatch.setattr(Calibrator, "_fit_sweep", recorded(fit_sweep))
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
