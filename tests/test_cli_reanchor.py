"""`wavemeter reanchor`: a calibration re-anchored to reference lines on the command line.

The simulated chip (``simulate --seed 1``) is read with its bias phase moved by 0.5 rad: the
old calibration is off by ``0.5 FSR / 2 pi`` (4 GHz). Re-anchored on ``k`` readings of its
lines, the test error is about ``CRLB sqrt(1 + 3/N + 1/k)`` (1.014 CRLB for the N = 400
sweep samples and k = 50); the RMS over M = 1000 test readings has a relative Monte-Carlo
standard error ``1 / sqrt(2 M)`` = 2.2 %, so the bound 1.2 CRLB is 8 standard errors above
the expectation and still fails for a residual bias of 0.65 CRLB.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.files.document import read_calibration_file
from wavemeter.io import write_table
from wavemeter.model.cone import wrap_to_period
from wavemeter.units import SPEED_OF_LIGHT_M_S

from .helpers import NOISE_W, POWER_W, one_error, random_test_frequencies, run_cli, simulated_files

BIAS_SHIFT_RAD = 0.5
LINE_READINGS = 50
TEST_READINGS = 1000
MAX_RMS_IN_CRLB = 1.2
#: |estimate - truth| / standard error beyond which a correct estimator is refuted
MAX_Z = 5.0


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    return simulated_files(tmp_path_factory.mktemp("reanchor"), test_rows=50, seed=1)


@pytest.fixture(scope="module")
def shifted() -> wm.Interferometer:
    """The simulate command's seed-1 device with its bias phase moved."""
    device = wm.Interferometer.table1(3, seed=1)
    return dataclasses.replace(device, bias_phase_rad=device.bias_phase_rad + BIAS_SHIFT_RAD)


def write_readings(path: Path, device, frequency_hz, seed: int, **columns) -> Path:
    """Readings of ``device`` at ``frequency_hz`` in the sweep's port columns, plus
    ``columns``."""
    powers = device.powers(frequency_hz, POWER_W, NOISE_W, np.random.default_rng(seed))
    ports = {f"p{k + 1}_w": powers[:, k] for k in range(device.ports)}
    write_table(path, {**columns, **ports}, "csv")
    return path


def test_data(device, seed: int) -> tuple[np.ndarray, np.ndarray]:
    frequency = random_test_frequencies(device, TEST_READINGS, np.random.default_rng(seed))
    return frequency, device.powers(frequency, POWER_W, NOISE_W, np.random.default_rng(seed + 1))


test_data.__test__ = False  # a helper, not a test


def wrapped_error_hz(calibration, device, frequency, readings) -> np.ndarray:
    return wrap_to_period(calibration.predict(readings) - frequency, device.true_fsr_hz)


def crlb_rms_hz(device, frequency) -> float:
    bound = wm.crlb_frequency_std(
        device.true_map(), device.phase_rad(frequency), POWER_W, NOISE_W, device.true_fsr_hz
    )
    return float(np.sqrt(np.mean(bound**2)))


def printed_shift_rad(out: str) -> float:
    return float(re.search(r"phase shift ([-+]\d+\.\d+) rad", out).group(1))


def test_one_line_brings_the_shifted_chip_back_to_the_noise_limit(files, shifted, tmp_path, capsys):
    line_hz = shifted.center_hz + 0.2 * shifted.true_fsr_hz
    readings = write_readings(tmp_path / "line.csv", shifted, np.full(LINE_READINGS, line_hz), 2)
    new = tmp_path / "today.wmcal.json"
    cal_bytes = files["cal"].read_bytes()
    code, out, err = run_cli(
        capsys, f"reanchor {files['cal']} {readings} --frequency {line_hz / 1e12!r}THz -o {new}"
    )
    assert code == 0, err
    assert f"{LINE_READINGS} readings of 1 line(s): {line_hz / 1e12:.6f} THz" in out
    assert "delay kept" in out and f"wrote {new}" in out
    assert files["cal"].read_bytes() == cal_bytes

    old, anchored = wm.load_calibration(files["cal"]), wm.load_calibration(new)
    frequency, powers = test_data(shifted, seed=3)
    crlb = crlb_rms_hz(shifted, frequency)
    # the old calibration reads the 0.5 rad shift as 0.5 FSR / 2 pi (4 GHz, 400 CRLB)
    stale = wrapped_error_hz(old, shifted, frequency, powers)
    assert np.mean(stale) == pytest.approx(
        BIAS_SHIFT_RAD * shifted.true_fsr_hz / (2 * np.pi), rel=0.01
    )
    error = wrapped_error_hz(anchored, shifted, frequency, powers)
    assert np.sqrt(np.mean(error**2)) <= MAX_RMS_IN_CRLB * crlb

    # the printed shift is the bias change, within its standard error and the calibration's
    record = anchored.diagnostics_["reanchor"]
    assert printed_shift_rad(out) == pytest.approx(record["phase_shift_rad"], abs=1e-6)
    line_powers = shifted.powers(line_hz, POWER_W, 0.0, 0)
    with_calibration, reading_only = (
        old.frequency_std_hz(line_powers, include_calibration=flag)[0] for flag in (True, False)
    )
    calibration_rad = np.sqrt(with_calibration**2 - reading_only**2) * 2 * np.pi / old.fsr_hz_
    std = np.hypot(record["phase_shift_std_rad"], calibration_rad)
    assert abs(record["phase_shift_rad"] - BIAS_SHIFT_RAD) < MAX_Z * std

    metadata = read_calibration_file(new).metadata
    assert metadata == {
        **read_calibration_file(files["cal"]).metadata,
        "reanchor_file": str(readings),
    }


def test_lines_by_wavelength_column(files, shifted, tmp_path, capsys):
    lines_hz = shifted.center_hz + np.array([-0.25, 0.25]) * shifted.true_fsr_hz
    frequency = np.repeat(lines_hz, LINE_READINGS)
    wavelength_nm = SPEED_OF_LIGHT_M_S / frequency * 1e9
    readings = write_readings(tmp_path / "lines.csv", shifted, frequency, 4, line=wavelength_nm)
    new = tmp_path / "today.wmcal.json"
    code, out, err = run_cli(
        capsys, f"reanchor {files['cal']} {readings} --x line --x-unit nm -o {new}"
    )
    assert code == 0, err
    shown = ", ".join(f"{line / 1e12:.6f}" for line in lines_hz)
    assert f"{2 * LINE_READINGS} readings of 2 line(s): {shown} THz" in out
    anchored = wm.load_calibration(new)
    np.testing.assert_allclose(anchored.diagnostics_["reanchor"]["lines_hz"], lines_hz, rtol=1e-14)
    test_frequency, powers = test_data(shifted, seed=5)
    error = wrapped_error_hz(anchored, shifted, test_frequency, powers)
    assert np.sqrt(np.mean(error**2)) <= MAX_RMS_IN_CRLB * crlb_rms_hz(shifted, test_frequency)


@pytest.mark.slow
def test_a_calibration_set_reports_every_window(shifted, tmp_path, capsys):
    sweep, cal = tmp_path / "wide.csv", tmp_path / "set.wmcal.json"
    assert run_cli(capsys, f"simulate -o {sweep} --span-fsr 3 --samples 900 --quiet")[0] == 0
    assert run_cli(capsys, f"calibrate {sweep} -o {cal} --per-fsr --quiet")[0] == 0
    line_hz = shifted.center_hz + 0.2 * shifted.true_fsr_hz
    readings = write_readings(tmp_path / "line.csv", shifted, np.full(LINE_READINGS, line_hz), 6)
    new = tmp_path / "today.wmcal.json"
    command = f"reanchor {cal} {readings} --frequency 194THz -o {new}"  # 12 FSR off
    err = one_error(*run_cli(capsys, command)[::2])
    assert "outside the calibrated span" in err and not new.exists()
    code, out, err = run_cli(capsys, f"reanchor {cal} {readings} --frequency {line_hz!r} -o {new}")
    assert code == 0, err
    windows = wm.load_calibration(new).windows_
    shown = [line for line in out.splitlines() if line.startswith("window ")]
    assert len(shown) == len(windows) == 3
    assert sum("interpolated from" in line for line in shown) == 2
    # one bias change for every window. Its standard error: the lines' (50 readings of
    # ~1.2e-3 rad, the CRLB's 9.7 MHz in phase: 1.7e-4 rad) with the window's own bias
    # error (300 sweep samples: 1.2e-3 sqrt(3 / 300) = 1.2e-4 rad), 2.1e-4 rad; 0.002 rad
    # is 10 of them, and 0.25 % of the shift
    for line in shown:
        assert printed_shift_rad(line) == pytest.approx(BIAS_SHIFT_RAD, abs=0.002)


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--frequency 193.4THz --x frequency_hz", "exactly one of the two"),
        ("", "exactly one of the two"),
        ("--frequency 193.4THz --x-unit nm", "--x-unit is the unit of --x COL"),
        ("--frequency 193.4", "did you mean 193.4THz?"),
    ],
)
def test_frequency_options_refused_before_any_work(files, tmp_path, capsys, options, expected):
    out = tmp_path / "new.wmcal.json"
    err = one_error(
        *run_cli(capsys, f"reanchor {files['cal']} {files['test']} {options} -o {out}")[::2]
    )
    assert expected in err and not out.exists()


def test_a_baseline_calibration_is_refused_naming_its_method(files, tmp_path, capsys):
    baseline, out = tmp_path / "conv.wmcal.json", tmp_path / "new.wmcal.json"
    command = f"calibrate {files['sweep']} -o {baseline} --method conventional --quiet"
    assert run_cli(capsys, command)[0] == 0
    command = f"reanchor {baseline} {files['test']} --x true_frequency_hz -o {out}"
    err = one_error(*run_cli(capsys, command)[::2])
    assert "a conventional calibration cannot be re-anchored" in err and not out.exists()


@pytest.mark.parametrize("target", ["existing", "cal", "readings"])
def test_an_existing_output_or_an_input_is_never_replaced_without_force(
    files, tmp_path, capsys, target
):
    out = {"existing": tmp_path / "old.wmcal.json", "cal": files["cal"], "readings": files["test"]}
    out = out[target]
    if target == "existing":
        out.write_text("keep me")
    before = out.read_bytes()
    command = f"reanchor {files['cal']} {files['test']} --x true_frequency_hz -o {out}"
    err = one_error(*run_cli(capsys, command)[::2])
    assert (
        ("already exists" in err and "--force" in err)
        if target == "existing"
        else "is the input file" in err
    )
    assert out.read_bytes() == before
    if target != "existing":
        err = one_error(*run_cli(capsys, f"{command} --force")[::2])
        assert "is the input file" in err and out.read_bytes() == before
