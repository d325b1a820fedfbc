"""Shared fixtures and helpers: seeded randomness, simulated devices, the command line."""

from __future__ import annotations

import os

# the suite's arrays are small: one BLAS thread per process avoids oversubscribing the
# 2-core machines, where threaded OpenBLAS makes small factorisations 10-100x slower
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import shlex  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

import wavemeter as wm  # noqa: E402
from wavemeter.cli import main  # noqa: E402

POWER_W = 1e-3
NOISE_W = 5e-7  # Table 1: 5e-4 mW at 1 mW

#: the default run's property tests: the same examples on every run and machine (drawn from
#: each test's own source, not a clock), no example database carrying a failure from one run
#: to the next, and no check that depends on timing (a deadline, the too-slow health check)
DEFAULT_PROFILE = "wavemeter"
#: ``make fuzz``: new examples from the seed it prints (``--hypothesis-seed``), still without
#: a database: a failure is repeated with ``make fuzz FUZZ_SEED=<seed>``
FUZZ_PROFILE = "fuzz"
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


def random_test_frequencies(device: wm.Interferometer, samples: int, rng) -> np.ndarray:
    """Frequencies (Hz) uniform over one true FSR about the device centre."""
    half = device.true_fsr_hz / 2
    return device.center_hz + rng.uniform(-half, half, samples)


def run_cli(capsys, command: str) -> tuple[int, str, str]:
    """Run ``wavemeter COMMAND`` in process: exit code, stdout, stderr."""
    code = main(shlex.split(command))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_error(code: int, err: str) -> str:
    """The single ``error:`` line of a refused command (exit code 2)."""
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("error: "), err
    return err


def simulated_files(folder: Path, test_rows: int, seed: int = 1) -> dict[str, Path]:
    """A simulated sweep with a test file in ``folder``, and its learned calibration."""
    sweep, cal = folder / "sweep.csv", folder / "chip.wmcal.json"
    simulate = f"simulate -o {sweep} --seed {seed} --samples 400 --test {test_rows} --quiet"
    assert main(shlex.split(simulate)) == 0
    assert main(shlex.split(f"calibrate {sweep} -o {cal} --quiet")) == 0
    return {"sweep": sweep, "test": folder / "sweep-test.csv", "cal": cal}


#: calibration temperatures of the thermal tests (K): four, symmetric about the simulator's
#: reference temperature 293.15 K, the closest two 1.5 K apart
THERMAL_SWEEP_TEMPERATURES_K = (289.15, 292.4, 293.9, 297.15)


def thermal_sweep(
    device: wm.Interferometer,
    samples_per_temperature: int,
    noise_w: float,
    rng,
    temperatures_k=THERMAL_SWEEP_TEMPERATURES_K,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-FSR sweeps of a device at several temperatures, stacked in acquisition order.

    Returns
    -------
    powers : ndarray, shape (N, n), W
    frequency_hz : ndarray, shape (N,), Hz
    temperature_k : ndarray, shape (N,), K (the true chip temperature of each reading)
    """
    frequency = device.sweep_hz(samples_per_temperature)
    generator = np.random.default_rng(rng)
    powers = [
        device.powers(frequency, POWER_W, noise_w, rng=generator, temperature_k=temperature)
        for temperature in temperatures_k
    ]
    count = len(temperatures_k)
    return (
        np.vstack(powers),
        np.tile(frequency, count),
        np.repeat(np.asarray(temperatures_k, dtype=float), frequency.size),
    )
