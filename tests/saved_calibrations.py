"""Saved calibrations of every registered method with readings of their devices, and the
checks every loaded file must pass: the loader's tests and fuzzers share them."""

from __future__ import annotations

import contextlib
import functools
import io
import json
import tempfile
import warnings
from pathlib import Path

import numpy as np

import wavemeter as wm
from wavemeter.cli import main
from wavemeter.io import write_table

from .helpers import NOISE_W, POWER_W, thermal_sweep

#: text that betrays a Python internal in a message meant for a user
INTERNALS = (
    "Traceback",
    "np.float64(",
    "<class ",
    "NoneType",
    "object has no attribute",
    "{'",  # a Python dict, where a file holds JSON
    "dtype",
    "inhomogeneous",
    "got None",
)

#: the cascade's design FSRs (Hz) and band
CASCADE_FSRS_HZ, CASCADE_BAND_HZ = (1e12, 100e9), 0.8e12


@functools.cache
def fitted() -> dict[str, tuple]:
    """A fitted calibrator of every registered method (the learned one with the ml
    retrieval), each with readings of its device: (calibrator, powers, frequency,
    temperature or None)."""
    device = wm.Interferometer.table1(3, seed=12)
    frequency = device.sweep_hz(402, span_fsr=2.0)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=12)
    one = slice(100, 301)  # one FSR for the single-FSR calibrators
    test_hz = device.center_hz + np.linspace(-20e9, 20e9, 16)
    test = (device.powers(test_hz, POWER_W, NOISE_W, rng=13), test_hz, None)
    single = (readings[one], frequency[one])
    result = {
        "learned": wm.Calibrator(50e9, retrieval="ml").fit(*single),
        "set": wm.CalibrationSet(50e9).fit(readings, frequency),
        "conventional": wm.ConventionalCalibrator(50e9).fit(*single),
        "ellipse": wm.EllipseCalibrator(50e9).fit(*single),
        "plane": wm.PlaneEllipseCalibrator(50e9).fit(*single),
        "extended": wm.ExtendedConventionalCalibrator(50e9).fit(*single),
        "nonlinear": wm.NonlinearFitCalibrator(50e9).fit(*single),
        "wideband": wm.WidebandCalibrator(50e9).fit(readings, frequency),
        "reference_free": wm.ReferenceFreeCalibrator(50e9).fit(*single),
    }
    result = {name: (cal, *test) for name, cal in result.items()}
    warm = device.with_thermal("sin")
    powers, sweep_hz, temperature = thermal_sweep(warm, 150, NOISE_W, rng=14)
    thermal = wm.ThermalCalibrator(50e9).fit(powers, sweep_hz, temperature_k=temperature)
    reference = np.full(test_hz.size, wm.Interferometer.reference_temperature_k)
    result["thermal"] = (
        thermal,
        warm.powers(test_hz, POWER_W, NOISE_W, rng=15),
        test_hz,
        reference,
    )
    chain = wm.CascadeInterferometer.table1(CASCADE_FSRS_HZ, ports=3, seed=7, spectral=None)
    band_hz = chain.center_hz + CASCADE_BAND_HZ * np.linspace(-0.5, 0.5, 600)
    cascade = wm.CascadeCalibrator(fsr_hz=CASCADE_FSRS_HZ).fit(
        chain.powers(band_hz, POWER_W, NOISE_W, rng=16), band_hz
    )
    chain_hz = chain.center_hz + np.linspace(-0.3, 0.3, 16) * CASCADE_BAND_HZ
    result["cascade"] = (cascade, chain.powers(chain_hz, POWER_W, NOISE_W, rng=17), chain_hz, None)
    return result


@functools.cache
def documents() -> dict[str, dict]:
    """The saved document of each calibrator of :func:`fitted`."""
    result = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, (cal, *_) in fitted().items():
            path = Path(folder) / f"{name}.json"
            wm.save_calibration(cal, path, {"sweep_file": "sweep.csv", "rows": 402})
            result[name] = json.loads(path.read_text())
    return result


def inputs_of(calibrator, frequency_hz, temperature_k) -> dict:
    """The per-reading inputs the calibrator declares (the truth as the coarse value)."""
    inputs = {}
    if "coarse_hz" in calibrator.requires:
        inputs["coarse_hz"] = frequency_hz
    if "temperature_k" in calibrator.requires:
        inputs["temperature_k"] = (
            wm.Interferometer.reference_temperature_k if temperature_k is None else temperature_k
        )
    return inputs


def usable(calibrator, name: str) -> None:
    """A loaded calibrator predicts finite numbers where it reads, states finite positive
    standard deviations, and reports itself."""
    _, powers, frequency, temperature = fitted()[name]
    if calibrator.n_ports_ == powers.shape[1]:
        inputs = inputs_of(calibrator, frequency, temperature)
        flags = calibrator.flags(powers, **inputs)
        read = flags & wm.ReadingFlag.INVALID == 0
        predicted = calibrator.predict(powers, **inputs)
        assert np.all(np.isfinite(predicted[read]))
        assert np.all(np.isfinite(calibrator.phase(powers, **inputs)[read]))
        if "frequency_std" in calibrator.capabilities:
            std = calibrator.frequency_std_hz(powers, **inputs)[read]
            assert np.all(np.isfinite(std) & (std > 0))
    assert calibrator.summary().text


def write_test_files(folder: Path) -> Path:
    """Each calibrator's readings as a test file ``<name>-test.csv`` (truth, ports,
    temperature) in ``folder``."""
    for name, (_, powers, frequency, temperature) in fitted().items():
        columns = {"true_frequency_hz": frequency}
        if temperature is not None:
            columns["temperature_k"] = temperature
        columns |= {f"p{k + 1}_w": powers[:, k] for k in range(powers.shape[1])}
        write_table(folder / f"{name}-test.csv", columns, "csv")
    return folder


def run(arguments: list[str]) -> tuple[int, str]:
    """``wavemeter ARGUMENTS`` in process: exit code and stderr. Any exception but a
    clean refusal propagates (a numpy RuntimeWarning is one)."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stdout(stdout):
        warnings.simplefilter("error", RuntimeWarning)
        with contextlib.redirect_stderr(stderr):
            code = main(arguments)
    return code, stderr.getvalue()


def check_commands(
    path: Path, calibrator, name: str, folder: Path, refusal_allowed: bool = True
) -> None:
    """`wavemeter info`, `measure` and `evaluate` on a calibration file: exit 0, or 2 with
    one error line (where ``refusal_allowed``); never a traceback or a Python repr."""
    test = folder / f"{name}-test.csv"
    out = folder / "out.csv"
    out.unlink(missing_ok=True)
    commands = (
        ["info", str(path)],
        ["measure", str(path), str(test), "-o", str(out), "--quiet"]
        + (["--coarse", "true_frequency_hz"] if "coarse_hz" in calibrator.requires else []),
        ["evaluate", str(path), str(test)],
    )
    for arguments in commands:
        code, errors = run(arguments)
        assert code in ((0, 2) if refusal_allowed else (0,)), errors
        assert not any(internal in errors for internal in INTERNALS), errors
        if code == 2:
            assert errors.startswith("error: ") and errors.count("\n") == 1, errors
