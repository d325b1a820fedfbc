"""The residual a sweep's readings share, learned for OFF_MODEL, in every calibrator with a
cone map: the thermal one, a set's windows, a sweep at a varying power (the residual's
power terms), a long sweep (learned from every k-th reading), and through files.

The model error is the benchmark's: detectors that compress by 5 % at the sweep's largest
reading (``benchmarks/offmodel.py``), read alike in the sweep and in fresh readings.
"""

from __future__ import annotations

import importlib
import warnings
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm

from .helpers import NOISE_W, POWER_W, thermal_sweep

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
OFF_MODEL = int(wm.ReadingFlag.OFF_MODEL)


@pytest.fixture(scope="module")
def bench():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("offmodel")


@pytest.fixture(scope="module")
def device() -> wm.Interferometer:
    return wm.Interferometer.table1(3, seed=7)


def fitted(calibrator, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return calibrator.fit(*args, **kwargs)


def off_model_share(calibration, readings, **inputs) -> float:
    return float(np.mean(calibration.flags(readings, **inputs) & OFF_MODEL > 0))


def reloaded(calibration, folder: Path):
    path = folder / "cal.wmcal.json"
    calibration.save(path)
    return wm.load_calibration(path)


def glitched(readings, size_w, rng) -> np.ndarray:
    """Each reading with one random port moved by ``size_w`` (n,) W, random sign."""
    rows = np.arange(readings.shape[0])
    port = rng.integers(0, readings.shape[1], rows.size)
    moved = readings.copy()
    moved[rows, port] += rng.choice([-1.0, 1.0], rows.size) * size_w[port]
    return moved


def test_a_thermal_calibration_learns_the_residual_and_keeps_it(bench, device, tmp_path):
    """A thermally compensated calibration of compressing detectors: the residual is
    learned at the map's phase (before the temperature's correction), fresh readings at
    calibrated temperatures are not flagged, and a file gives the same flags."""
    thermal = device.with_thermal("sin")
    powers, frequency, temperature = thermal_sweep(thermal, 300, NOISE_W, 1)
    largest = float(powers.max())
    calibration = fitted(
        wm.ThermalCalibrator(),
        bench.compressed(powers, largest),
        frequency,
        temperature_k=temperature,
    )
    assert calibration.off_model_basis_.residual is not None
    rng = np.random.default_rng(8)
    kelvin = rng.uniform(290.0, 296.0, 600)
    truth = device.center_hz + rng.uniform(-0.5, 0.5, kelvin.size) * device.true_fsr_hz
    rows = np.vstack(
        [
            thermal.powers([f], POWER_W, NOISE_W, rng=rng, temperature_k=t)
            for f, t in zip(truth, kelvin, strict=True)
        ]
    )
    good = bench.compressed(rows, largest)
    assert off_model_share(calibration, good, temperature_k=kelvin) <= 0.01
    faulty = glitched(good, 100 * bench.scatter(calibration), rng)
    flags = calibration.flags(np.vstack([good, faulty]), temperature_k=np.tile(kelvin, 2))
    assert np.mean(flags[kelvin.size :] & OFF_MODEL > 0) >= 0.9  # gross glitches
    loaded = reloaded(calibration, tmp_path)
    assert loaded.off_model_basis_ == calibration.off_model_basis_
    np.testing.assert_array_equal(
        loaded.flags(np.vstack([good, faulty]), temperature_k=np.tile(kelvin, 2)), flags
    )


def test_each_window_of_a_set_learns_its_own_residual(bench, device, tmp_path):
    sweep_hz = device.sweep_hz(3000, span_fsr=3.0)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=3)
    largest = float(sweep.max())
    calibration = fitted(wm.CalibrationSet(fsr_hz=50e9), bench.compressed(sweep, largest), sweep_hz)
    bases = [window.off_model_basis_ for window in calibration.windows_]
    assert len(bases) == 3 and all(basis.residual is not None for basis in bases)
    rng = np.random.default_rng(6)
    truth = rng.uniform(sweep_hz.min(), sweep_hz.max(), 1500)
    good = bench.compressed(device.powers(truth, POWER_W, NOISE_W, rng=rng), largest)
    assert off_model_share(calibration, good, coarse_hz=truth) <= 0.01
    loaded = reloaded(calibration, tmp_path)
    assert [window.off_model_basis_ for window in loaded.windows_] == bases
    np.testing.assert_array_equal(
        loaded.flags(good, coarse_hz=truth), calibration.flags(good, coarse_hz=truth)
    )


def test_a_residual_that_grows_with_the_power_is_learned_with_it(bench, device):
    """Compression's residual grows with the source power (``-0.05 p^2 / p_max``): swept at
    a power that varies by +-20 % (with a monitor), the residual takes the normalised
    source power as well as the phase, and fresh readings over that range of powers are not
    flagged; beyond it the power term is held at the range's edge."""
    frequency = device.sweep_hz(2001)
    power = POWER_W * (1.0 + 0.2 * np.sin(np.arange(frequency.size) / 37.0))
    sweep = device.powers(frequency, power, NOISE_W, rng=5)
    largest = float(sweep.max())
    calibration = fitted(
        wm.Calibrator(fsr_hz=50e9),
        bench.compressed(sweep, largest),
        frequency,
        power_monitor_w=power,
    )
    residual = calibration.off_model_basis_.residual
    assert residual.power_degree >= 1
    low, high = residual.power_range
    assert 0.75 < low < 0.85 and 1.15 < high < 1.25  # the sweep's 1st and 99th percentiles
    rng = np.random.default_rng(9)
    truth = device.center_hz + rng.uniform(-0.5, 0.5, 3000) * device.true_fsr_hz
    powers = POWER_W * rng.uniform(0.8, 1.2, truth.size)
    good = bench.compressed(device.powers(truth, powers, NOISE_W, rng=rng), largest)
    assert off_model_share(calibration, good) <= 0.01


def test_a_long_sweep_learns_from_every_kth_reading(bench, device):
    """Beyond 2^14 readings the residual is learned from every k-th: 20001 readings, every
    2nd."""
    frequency = device.sweep_hz(20001)
    sweep = device.powers(frequency, POWER_W, NOISE_W, rng=2)
    largest = float(sweep.max())
    calibration = fitted(wm.Calibrator(fsr_hz=50e9), bench.compressed(sweep, largest), frequency)
    basis = calibration.off_model_basis_
    assert basis.readings == 20001 and basis.residual.readings == 10001
    assert f"on {basis.residual.readings} readings" in str(calibration.summary())
    rng = np.random.default_rng(1)
    truth = device.center_hz + rng.uniform(-0.5, 0.5, 2000) * device.true_fsr_hz
    good = bench.compressed(device.powers(truth, POWER_W, NOISE_W, rng=rng), largest)
    assert off_model_share(calibration, good) <= 0.01


def test_a_residual_is_learned_only_where_the_sweep_shows_a_model_error(device):
    """A clean sweep learns nothing: its record has no residual (the detector-noise test),
    and its summary says there is no model error."""
    frequency = device.sweep_hz(2001)
    calibration = fitted(
        wm.Calibrator(fsr_hz=50e9), device.powers(frequency, POWER_W, NOISE_W, rng=4), frequency
    )
    basis = calibration.off_model_basis_
    assert basis.residual is None and basis.scale == 1.0
    assert "no model error" in str(calibration.summary())
