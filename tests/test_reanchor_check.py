"""Re-anchoring checks its reference: readings of one line must scatter like one line (issue
29, item 4).

The statistic is the F ratio of a line's phase variance to the calibration's: under the
model (Gaussian detector noise at the calibration's level) its p-value is uniform, so with
fixed seeds a right input is accepted without a warning (each warns with probability
``WARN_P_VALUE``), while readings at random frequencies scatter ~1.8 rad against ~1 mrad and
are refused with p = 0. A line read with twice the calibration's noise scatters 2 times the
expected: beyond any p-value with 200 readings, below the refusal ratio of 10: warned. With
25 times the noise: refused.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy import stats

import wavemeter as wm
from wavemeter.calibration.models.reference_check import (
    REFERENCE_CAUSE,
    REFUSE_P_VALUE,
    REFUSE_SCATTER_RATIO,
    WARN_P_VALUE,
    reference_scatter,
)
from wavemeter.io import write_table

from .helpers import NOISE_W, POWER_W, one_error, run_cli, simulated_files, thermal_sweep

#: the seeds of the right inputs: each warns with probability WARN_P_VALUE (1e-3)
SEEDS = (1, 2, 3, 4, 5)


@pytest.fixture(scope="module")
def device() -> wm.Interferometer:
    return wm.Interferometer.table1(3, seed=5)


@pytest.fixture(scope="module")
def calibration(device):
    frequency = device.sweep_hz(600)
    return wm.Calibrator(50e9).fit(device.powers(frequency, POWER_W, NOISE_W, rng=6), frequency)


def line_readings(device, lines_hz, count: int, seed: int, noise_w: float = NOISE_W):
    frequency = np.repeat(np.atleast_1d(lines_hz), count)
    return frequency, device.powers(frequency, POWER_W, noise_w, np.random.default_rng(seed))


def quietly(function, *args, **kwargs):
    """Call, failing on any CalibrationWarning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        return function(*args, **kwargs)


def test_readings_at_random_frequencies_given_as_one_line_are_refused(device, calibration):
    """The issue's case: a test file of random frequencies re-anchored as one line."""
    rng = np.random.default_rng(7)
    frequency = device.center_hz + rng.uniform(-0.5, 0.5, 50) * device.true_fsr_hz
    powers = device.powers(frequency, POWER_W, NOISE_W, rng)
    with pytest.raises(wm.InputError) as caught:
        calibration.reanchor(powers, 193.4e12)
    message = str(caught.value)
    assert caught.value.parameter == "frequency_hz"
    assert "the 50 readings given as the line at 193.400000 THz" in message
    check = reference_scatter(
        calibration.phase(powers),
        np.full(50, 193.4e12),
        calibration.frequency_std_hz(powers, include_calibration=False)
        * (2 * np.pi / calibration.fsr_hz_),
    )
    observed, expected = check.lines[0].observed_rad, check.lines[0].expected_rad
    # random phases on the circle scatter by about pi / sqrt(3) = 1.8 rad
    assert 1.2 < observed < 2.2 and expected < 2e-3
    assert f"scatter by {observed:.3g} rad" in message and f"predicts {expected:.3g} rad" in message
    assert "p = 0 for 1 line(s) tested" in message


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("lines", [1, 3])
def test_right_readings_are_accepted_without_a_warning(device, calibration, seed, lines):
    half = 0.4 * device.true_fsr_hz
    lines_hz = device.center_hz + np.linspace(-half, half, lines)
    frequency, powers = line_readings(device, lines_hz, 40, seed)
    anchored = quietly(calibration.reanchor, powers, frequency)
    check = anchored.diagnostics_["reanchor"]["reference_check"]
    assert check["verdict"] == "ok" and check["p_value"] >= WARN_P_VALUE
    assert [line["readings"] for line in check["lines"]] == [40] * lines
    for line in check["lines"]:
        # sqrt(F) with 39 and ~600 degrees of freedom: 1 +- 0.11 (1 sd); 5 sd
        assert abs(line["scatter_ratio"] - 1) < 0.55
    assert "warnings" not in anchored.diagnostics_ or not [
        note for note in anchored.diagnostics_["warnings"] if note["cause"] == REFERENCE_CAUSE
    ]


def test_a_thermal_calibration_checks_its_reference_too():
    device = wm.Interferometer.table1(3, seed=8).with_thermal("sin")
    powers, frequency, temperature = thermal_sweep(device, 300, NOISE_W, rng=9)
    thermal = wm.ThermalCalibrator(50e9).fit(powers, frequency, temperature_k=temperature)
    line_hz = device.center_hz + 5e9
    lines = np.full(40, line_hz)
    right = device.powers(lines, POWER_W, NOISE_W, rng=10, temperature_k=295.0)
    anchored = quietly(thermal.reanchor, right, lines, temperature_k=295.0)
    assert anchored.diagnostics_["reanchor"]["reference_check"]["verdict"] == "ok"
    rng = np.random.default_rng(11)
    scattered_hz = device.center_hz + rng.uniform(-0.5, 0.5, 40) * device.true_fsr_hz
    wrong = device.powers(scattered_hz, POWER_W, NOISE_W, rng, temperature_k=295.0)
    with pytest.raises(wm.InputError, match="not readings of one line"):
        thermal.reanchor(wrong, lines, temperature_k=295.0)


def test_a_noisier_line_is_warned_and_the_warning_kept(device, calibration, tmp_path):
    """Twice the calibration's noise: 2 times the expected scatter, p ~ 0 with 200 readings,
    below the refusal ratio: a warning with cause and remedy, kept with the file."""
    frequency, powers = line_readings(device, device.center_hz, 200, 12, noise_w=2 * NOISE_W)
    with pytest.warns(wm.CalibrationWarning) as caught:
        anchored = calibration.reanchor(powers, frequency)
    notes = [note.message for note in caught if note.message.cause == REFERENCE_CAUSE]
    assert len(notes) == 1 and notes[0].remedy
    check = anchored.diagnostics_["reanchor"]["reference_check"]
    assert check["verdict"] == "warned" and check["p_value"] < WARN_P_VALUE
    assert 1.6 < check["lines"][0]["scatter_ratio"] < 2.4  # 2, its spread 0.1 with 200
    assert anchored.diagnostics_["warnings"][-1]["cause"] == REFERENCE_CAUSE
    path = tmp_path / "warned.wmcal.json"
    anchored.save(path)
    loaded = wm.load_calibration(path)
    assert loaded.diagnostics_["reanchor"]["reference_check"] == json.loads(json.dumps(check))
    text = loaded.summary().text
    assert "reference check  warned: scatter" in text
    assert f"warning          {REFERENCE_CAUSE}:" in text


def test_a_line_read_far_beyond_the_noise_is_refused(device, calibration):
    """25 times the noise: a scatter beyond REFUSE_SCATTER_RATIO at p ~ 0."""
    frequency, powers = line_readings(device, device.center_hz, 50, 13, noise_w=25 * NOISE_W)
    with pytest.raises(wm.InputError, match=r"times; F test on 49 and") as caught:
        calibration.reanchor(powers, frequency)
    assert f"beyond {REFUSE_SCATTER_RATIO:g} times at p < {REFUSE_P_VALUE:g}" in str(caught.value)


def test_one_reading_per_line_is_recorded_untested(device, calibration):
    frequency, powers = line_readings(device, device.center_hz, 1, 14)
    anchored = quietly(calibration.reanchor, powers, frequency)
    check = anchored.diagnostics_["reanchor"]["reference_check"]
    assert check["verdict"] == "untested" and check["p_value"] is None
    assert "reference check  untested: no line with two readings" in anchored.summary().text


def test_the_scatter_statistic_has_uniform_p_values_under_the_model():
    """Gaussian phases at their stated standard deviation: p-values uniform. Of 400 lines
    of 10 readings, the share below 0.05 is 0.05 +- 0.011 (binomial sd); 4 sd bounds it."""
    rng = np.random.default_rng(15)
    lines = np.repeat(np.arange(400.0) + 193e12, 10)
    std = rng.uniform(1e-3, 3e-3, lines.size)
    phase = 0.7 + std * rng.standard_normal(lines.size)
    check = reference_scatter(phase, lines, std)
    p_values = np.array([line.p_value for line in check.lines])
    assert abs(np.mean(p_values < 0.05) - 0.05) < 4 * np.sqrt(0.05 * 0.95 / 400)
    assert stats.kstest(p_values, "uniform").pvalue > 1e-3
    assert check.verdict in ("ok", "warned")  # the family-wise p of 400 lines


def test_the_f_test_widens_for_a_noise_estimated_on_few_degrees_of_freedom():
    """The same scatter (1.5 times) is less significant against a noise known from 5
    degrees of freedom than from an exact one."""
    rng = np.random.default_rng(16)
    std = np.full(30, 1e-3)
    phase = 1.5e-3 * rng.standard_normal(30)
    exact = reference_scatter(phase, np.full(30, 193e12), std)
    rough = reference_scatter(phase, np.full(30, 193e12), std, noise_dof=5)
    assert rough.p_value > exact.p_value
    assert rough.lines[0].ratio == exact.lines[0].ratio


def test_a_set_refuses_a_window_whose_line_is_not_one(device):
    frequency = device.center_hz + device.true_fsr_hz * np.linspace(-1.5, 1.5, 900)
    cal_set = wm.CalibrationSet(50e9).fit(device.powers(frequency, POWER_W, NOISE_W, 17), frequency)
    rng = np.random.default_rng(18)
    center = cal_set.windows_[1].center_hz_
    scattered = center + rng.uniform(-0.3, 0.3, 30) * device.true_fsr_hz
    with pytest.raises(wm.InputError, match="not readings of one line"):
        cal_set.reanchor(device.powers(scattered, POWER_W, NOISE_W, rng), np.full(30, center))
    right_hz, right = line_readings(device, center, 30, 19)
    anchored = quietly(cal_set.reanchor, right, right_hz)
    windows = anchored.diagnostics_["reanchor"]["windows"]
    assert windows[1]["reference_check"]["verdict"] == "ok"
    assert windows[0]["reference_check"] is None  # interpolated, no readings
    assert "reference check  ok" in anchored.summary().text


# ---------------------------------------------------------------------------- the command
def test_the_command_refuses_a_test_file_given_as_one_line(tmp_path, capsys):
    """The issue's command: a simulated test file (random frequencies) re-anchored with
    --frequency: one error line naming the readings file and the numbers, exit 2, no file."""
    files = simulated_files(tmp_path, test_rows=50, seed=1)
    out = tmp_path / "anchored.wmcal.json"
    code, _, err = run_cli(
        capsys, f"reanchor {files['cal']} {files['test']} --frequency 193.4THz -o {out}"
    )
    line = one_error(code, err)
    assert line.startswith(f"error: {files['test']}: reference readings: the 50 readings")
    assert "not readings of one line" in line and "p = 0" in line
    assert not out.exists()
    assert list(tmp_path.glob("*.tmp*")) == []


def test_the_command_prints_the_check_of_a_right_line(tmp_path, capsys):
    files = simulated_files(tmp_path, test_rows=4, seed=1)
    device = wm.Interferometer.table1(3, seed=1)
    line_hz = device.center_hz + 0.1 * device.true_fsr_hz
    frequency, powers = line_readings(device, line_hz, 40, 20)
    readings = tmp_path / "line.csv"
    write_table(readings, {f"p{k + 1}_w": powers[:, k] for k in range(3)}, "csv")
    out = tmp_path / "anchored.wmcal.json"
    code, output, err = run_cli(
        capsys, f"reanchor {files['cal']} {readings} --frequency {line_hz!r} -o {out}"
    )
    assert code == 0 and "warning" not in err, err
    assert "reference check ok (scatter " in output
    code, output, _ = run_cli(capsys, f"info {out}")
    assert code == 0 and "reference check  ok: scatter" in output
