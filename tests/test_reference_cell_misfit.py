"""Fit diagnostics on a reference cell's corrected axis (issue 29, "the right cause").

The corrected axis is the meter's own phase, smoothed along the sweep (a cubic
Savitzky-Golay window of 101 readings), mapped through the lines' correction: it follows
the readings' phase noise up to the smoothing's bandwidth, so a phase error smooth along
the rows at those scales is the axis's. Before, the fit diagnostics tested it as a misfit:
the README's clean cell example (residual 1.02x the noise, lag-1 correlation 0.02) warned
``other_misfit`` with a remedy naming WidebandCalibrator, the method in use. Now those
directions are the fit's, and a real model error on the same set-up (a source-power drift
of 0.2 %, a 2 % compression of every detector, a wandering background on one port of 0.6x
its noise) is still named. The sweeps: 8000 readings over 1 THz (20 FSRs) of a Table 1
3-port device, the laser at its specified accuracy, the simulated cell beside it.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.simulation import ReferenceCell, laser_sweep

from .helpers import NOISE_W, POWER_W, run_cli

BAND_HZ = (192.9e12, 193.9e12)
SAMPLES = 8000
#: a bound on the recorded axis's error: the laser's specified 10 pm is 1.27 GHz
AXIS_ERROR_HZ = 1.3e9


def recording(seed: int = 1, fault: str | None = None):
    """The sweep's recorded axis, its readings (with ``fault``) and the cell's keywords."""
    rng = np.random.default_rng([29, seed])
    cell = ReferenceCell.simulated(rng=rng.spawn(1)[0])
    sweep = laser_sweep(BAND_HZ, SAMPLES, "tls-spec", rng=rng.spawn(1)[0])
    device = wm.Interferometer.table1(3, seed=seed)
    time = np.linspace(0.0, 1.0, SAMPLES)
    power = POWER_W * (1 + 0.002 * np.sin(6 * np.pi * time)) if fault == "drift" else POWER_W
    powers = device.powers(sweep.true_hz, power, NOISE_W, rng=rng.spawn(1)[0])
    if fault == "compression":  # every detector 2 % below linear at the largest reading
        powers = powers - 0.02 * powers**2 / powers.max()
    elif fault == "background":  # port 1's background wanders by 0.6x its noise
        powers[:, 0] += 0.6 * NOISE_W * np.sin(14 * np.pi * time)
    keywords = {
        "reference_transmission": cell.transmission(sweep.true_hz, rng=rng.spawn(1)[0]),
        "reference_lines": cell.lines,
        "reference_pressure_pa": cell.nominal_pressure_pa,
        "reference_pressure_std_pa": cell.pressure_std_pa,
        "axis_error_hz": AXIS_ERROR_HZ,
    }
    return sweep, powers, keywords


def fitted(calibrator, *args, **keywords):
    """The calibrator fitted, and the warnings its fit raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", wm.CalibrationWarning)
        calibrator.fit(*args, **keywords)
    return calibrator, [note.message for note in caught]


def test_a_clean_wideband_calibration_on_the_corrected_axis_warns_nothing():
    """Seed 1 warned ``other_misfit`` before (the smooth test, p 4e-7)."""
    sweep, powers, cell = recording()
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        calibration = wm.WidebandCalibrator(50e9).fit(powers, sweep.recorded_hz, **cell)
    fit = calibration.diagnostics_["fit"]
    # the residual is the noise: within 5 % of it on every port (8000 readings: the ratio's
    # standard error is 1 %)
    assert np.all(np.abs(np.array(fit["noise_ratio"]) - 1.0) < 0.05), fit["noise_ratio"]
    assert fit["p_values"]["smooth"] > 0.01


def test_the_axis_bandwidth_is_the_smoothings():
    """The axis follows the meter's phase up to where the smoothing's gain falls below
    0.1: for 101 readings, 0.0162 cycles per reading (its half-power point is 0.0126)."""
    from wavemeter.reference import smoothing_bandwidth

    assert smoothing_bandwidth(101) == pytest.approx(0.0162, abs=2e-4)
    assert smoothing_bandwidth(11) > 5 * smoothing_bandwidth(101)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("fault", "cause"),
    [("drift", "power_drift"), ("compression", "other_misfit"), ("background", "other_misfit")],
)
def test_a_real_model_error_on_the_same_setup_is_still_named(fault, cause):
    sweep, powers, cell = recording(fault=fault)
    calibration, notes = fitted(wm.WidebandCalibrator(50e9), powers, sweep.recorded_hz, **cell)
    assert [note.cause for note in notes] == [cause], [str(note) for note in notes]
    # no remedy suggests the method in use
    assert all("WidebandCalibrator" not in note.remedy for note in notes)
    assert calibration.method == "wideband"


@pytest.mark.slow
def test_a_remedy_suggests_the_wide_band_method_only_to_another_method():
    """The compressed detectors over 20 FSRs, fitted with one map on the recorded axis:
    the learned calibration is told of the wide-band one, the wide-band one is not."""
    sweep, powers, _ = recording(fault="compression")
    learned = fitted(wm.Calibrator(50e9), powers, sweep.true_hz)[1]
    wide = fitted(wm.WidebandCalibrator(50e9), powers, sweep.true_hz)[1]
    assert [note.cause for note in wide] == ["other_misfit"]
    assert "WidebandCalibrator" not in wide[0].remedy and "CalibrationSet" in wide[0].remedy
    assert any("WidebandCalibrator" in note.remedy for note in learned)


def warned(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("warning:")]


def test_the_readme_cell_example_warns_nothing(capsys, tmp_path):
    """The exact commands of the issue (``simulate --help`` and ``calibrate --help``)."""
    sweep, lines, out = tmp_path / "cell.csv", tmp_path / "cell-lines.csv", tmp_path / "abs.json"
    code, _, err = run_cli(
        capsys,
        f"simulate -o {sweep} --span-fsr 20 --samples 8000 --sweep-axis tls-spec "
        "--reference-cell hcn-like",
    )
    assert code == 0 and lines.is_file(), err
    code, text, err = run_cli(
        capsys,
        f"calibrate --method wideband {sweep} -o {out} --reference-column cell_transmission "
        f"--lines {lines} --cell-pressure 13.3kPa --axis-error 1.3GHz",
    )
    assert code == 0, err
    assert not warned(err), err
    assert "warnings         none" in text


@pytest.mark.slow
@pytest.mark.parametrize(
    ("simulate", "calibrate"),
    [
        ("--seed 1", "--fsr 50GHz"),
        ("--ports 4 --seed 2 --test 2000", "--fsr 50GHz"),
        (
            "--cascade 5THz,500GHz,50GHz --spectral sin --samples 8000 --test 2000",
            "--method cascade --fsr 5THz,500GHz,50GHz --stage-ports 1-3/4-6/7-9",
        ),
    ],
    ids=["plain", "hybrid", "cascade"],
)
def test_the_help_examples_on_clean_simulated_data_warn_nothing(
    capsys, tmp_path, simulate, calibrate
):
    """Issue 29: the README's cascade example warned ``other_misfit`` on clean data."""
    sweep, out = tmp_path / "sweep.csv", tmp_path / "cal.wmcal.json"
    code, _, err = run_cli(capsys, f"simulate -o {sweep} {simulate}")
    assert code == 0, err
    code, text, err = run_cli(capsys, f"calibrate {sweep} -o {out} {calibrate}")
    assert code == 0, err
    assert not warned(err), err
    assert "warnings         none" in text
