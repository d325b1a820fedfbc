"""Dead (dark-noise only), stuck and saturated ports: named, with numbers, never silent.

Significance is judged from the physics of a least-squares fringe fit: without a fringe
the squared significance ``z^2`` of a port's fitted amplitude is chi-square with 2 degrees
of freedom (mean 2, standard deviation 2), whatever part of an FSR the sweep covers; a
port is dead below 5 standard errors. Table 1 fringes are ~1e4 standard errors.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.checks.port_health import MIN_FRINGE_Z, port_health

from .helpers import NOISE_W, POWER_W, darken


def sweep(ports: int, seed: int, samples: int = 2001, span_fsr: float = 1.0):
    device = wm.Interferometer.table1(ports, seed=seed)
    frequency = device.sweep_hz(samples, span_fsr=span_fsr)
    return device, frequency, device.powers(frequency, POWER_W, NOISE_W, rng=seed)


def test_one_dead_port_of_four_warns_naming_it_and_still_fits(tmp_path):
    device, frequency, readings = sweep(4, seed=1)
    with pytest.warns(wm.CalibrationWarning) as record:
        cal = wm.Calibrator(50e9).fit(darken(readings, [2]), frequency)
    (warning,) = record
    assert warning.message.cause == "dead_port" and warning.message.remedy
    message = str(warning.message)
    assert "p3" in message and "p1" not in message and "standard errors" in message
    assert cal.fsr_hz_ == pytest.approx(device.true_fsr_hz, rel=1e-4)
    ports = {port["name"]: port for port in cal.diagnostics_["ports"]}
    assert ports["p3"]["status"] == "dead" and ports["p3"]["fringe_z"] < MIN_FRINGE_Z
    assert [ports[name]["status"] for name in ("p1", "p2", "p4")] == ["ok"] * 3
    # the dark port's own residual is its dark noise (2001 readings: 1.6 % standard error)
    assert ports["p3"]["noise_std_w"] == pytest.approx(NOISE_W, rel=0.08)
    assert cal.diagnostics_["warnings"][0]["cause"] == "dead_port"
    cal.save(tmp_path / "cal.json")
    assert json.loads((tmp_path / "cal.json").read_text())["diagnostics"] == cal.diagnostics_
    assert wm.load_calibration(tmp_path / "cal.json").diagnostics_ == cal.diagnostics_


@pytest.mark.parametrize(("ports", "dead"), [(3, [0, 2]), (3, [1]), (4, [1, 3])])
def test_too_few_good_ports_is_an_error_naming_the_dead_ones(ports, dead):
    _, frequency, readings = sweep(ports, seed=2)
    with pytest.raises(wm.InputError, match="carry no usable fringe") as info:
        wm.Calibrator(50e9).fit(darken(readings, dead), frequency)
    message = str(info.value)
    names = [f"p{k + 1}" for k in range(ports)]
    assert all(names[k] in message for k in dead)
    assert f"{ports - len(dead)} good port(s) remain" in message


def test_a_stuck_port_is_named():
    _, frequency, readings = sweep(4, seed=3)
    stuck = readings.copy()
    stuck[:, 0] = 2e-4
    with pytest.warns(wm.CalibrationWarning, match=r"p1 is stuck \(all 2001 readings equal\)"):
        wm.Calibrator(50e9).fit(stuck, frequency)


@pytest.mark.parametrize("ports", [3, 4])
def test_a_saturated_port_is_named(ports):
    """A detector clipping at 70 % of the port's peak: about a third of its readings."""
    _, frequency, readings = sweep(ports, seed=4)
    clipped = readings.copy()
    level = 0.7 * clipped[:, 1].max()
    clipped[:, 1] = np.minimum(clipped[:, 1], level)
    share = np.mean(clipped[:, 1] == level)
    if ports == 3:
        with pytest.raises(wm.InputError, match="p2 is saturated"):
            wm.Calibrator(50e9).fit(clipped, frequency)
    else:
        with pytest.warns(wm.CalibrationWarning, match=f"p2 is saturated .{int(share * 2001)}"):
            wm.Calibrator(50e9).fit(clipped, frequency)


@pytest.mark.slow
@pytest.mark.parametrize(
    "make",
    [wm.Calibrator, wm.ConventionalCalibrator, wm.PlaneEllipseCalibrator, wm.CalibrationSet],
    ids=["learned", "conventional", "plane", "set"],
)
def test_every_calibrator_checks_its_ports(make):
    _, frequency, readings = sweep(4, seed=5, samples=4000, span_fsr=2.0)
    with pytest.warns(wm.CalibrationWarning, match="p4") as record:
        cal = make(50e9).fit(darken(readings, [3]), frequency)
    assert len(record) == 1  # a calibration set warns once, not once per window
    assert cal.diagnostics_["warnings"][0]["cause"] == "dead_port"


@pytest.mark.slow
@pytest.mark.parametrize("ports", [3, 4])
def test_table1_devices_raise_no_warning(ports):
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        for seed in range(20):
            _, frequency, readings = sweep(ports, seed=seed)
            cal = wm.Calibrator(50e9).fit(readings, frequency)
            assert min(port["fringe_z"] for port in cal.diagnostics_["ports"]) > 1e3


@pytest.mark.slow
@pytest.mark.parametrize("span_fsr", [pytest.param(0.3, marks=pytest.mark.slow), 1.0])
def test_significance_of_a_port_without_fringe_is_chi_square_2(span_fsr):
    """Mean z^2 over 400 dark ports is 2 (chi-square, 2 dof): standard error 0.1, allow 5."""
    device, frequency, _ = sweep(3, seed=6, samples=500, span_fsr=span_fsr)
    center = 0.5 * (frequency.min() + frequency.max())
    squares = []
    for seed in range(400):
        readings = device.powers(frequency, POWER_W, NOISE_W, rng=seed)
        dark = darken(readings, [0], seed=seed)
        health = port_health(dark, frequency, center, device.delay_s, ["a", "b", "c"])
        squares.append(health[0].fringe_z ** 2)
    assert np.mean(squares) == pytest.approx(2.0, abs=0.5)


def test_a_two_port_ellipse_needs_only_the_ports_it_reads():
    _, frequency, readings = sweep(3, seed=7)
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        wm.EllipseCalibrator(50e9, ports=(0, 1)).fit(darken(readings, [2]), frequency)
    with pytest.raises(wm.InputError, match="p2 has a fringe amplitude.*needs at least 2"):
        wm.EllipseCalibrator(50e9, ports=(0, 1)).fit(darken(readings, [1]), frequency)
