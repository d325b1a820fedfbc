"""A design FSR the sweep cannot resolve, does not cover or contradicts is refused at once.

The cases of issue 15: ``fsr_hz`` given as 50, 5000, 50000 or 5e6 (GHz meant, or an alias)
on a sweep of a 50 GHz device. Each must give one InputError naming the estimate the
sweep itself shows, in well under a second (the timing bound is a hang guard, not a
benchmark). The estimate's tolerance comes from the FSR's own standard error on that
sweep (the fit's Cramer-Rao figure) and the 6 digits the message prints.
"""

from __future__ import annotations

import re
import time
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.checks.fsr_guard import estimate_fsr
from wavemeter.calibration.models.delay_search import MAX_GRID_POINTS, search_delay
from wavemeter.calibration.models.subsample import median_step_hz

from .helpers import NOISE_W, POWER_W

#: a hang guard: the refusal takes ~10 ms; the bad inputs used to allocate 24.6 GiB or run
#: for minutes
HANG_GUARD_S = 5.0
#: the message prints the estimate with 6 significant digits
PRINTED_RTOL = 5e-6


@pytest.fixture(scope="module")
def sweep():
    device = wm.Interferometer.table1(3, seed=7)
    frequency = device.sweep_hz(2001)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=1)
    return device, frequency, readings


@pytest.fixture(scope="module")
def fsr_sigma_hz(sweep):
    """Standard error of the FSR from this sweep (Hz), from a fit with the right design."""
    _, frequency, readings = sweep
    return wm.Calibrator(50e9).fit(readings, frequency).summary()["fsr_hz"].stderr


def suggested_fsr_hz(message: str) -> float:
    return float(re.search(r"set fsr_hz to about ([0-9.e+]+) Hz", message).group(1))


@pytest.mark.parametrize("fsr_hz", [50.0, 5e3, 5e4, 5e6, 5e8, 5e9])
def test_a_design_fsr_in_the_wrong_unit_is_refused_with_the_sweeps_own(sweep, fsr_sigma_hz, fsr_hz):
    device, frequency, readings = sweep
    start = time.perf_counter()
    with pytest.raises(wm.InputError) as info:
        wm.Calibrator(fsr_hz=fsr_hz).fit(readings, frequency)
    assert time.perf_counter() - start < HANG_GUARD_S
    assert info.value.parameter == "fsr_hz"
    message = str(info.value)
    assert f"fsr_hz={fsr_hz:.6g} Hz" in message
    tolerance = 5 * fsr_sigma_hz + PRINTED_RTOL * device.true_fsr_hz
    assert suggested_fsr_hz(message) == pytest.approx(device.true_fsr_hz, abs=tolerance)
    # a sweep of 25.7 MHz steps cannot sample a fringe shorter than 51.5 MHz (Nyquist)
    expected = "not resolved by the sweep" if fsr_hz < 2e8 else "far from the FSR the sweep"
    assert expected in message


@pytest.mark.parametrize(
    "make",
    [
        lambda fsr: wm.Calibrator(fsr),
        lambda fsr: wm.CalibrationSet(fsr),
        lambda fsr: wm.ConventionalCalibrator(fsr),
        lambda fsr: wm.EllipseCalibrator(fsr),
        lambda fsr: wm.PlaneEllipseCalibrator(fsr),
        lambda fsr: wm.ExtendedConventionalCalibrator(fsr),
        lambda fsr: wm.NonlinearFitCalibrator(fsr),
    ],
    ids=["learned", "set", "conventional", "ellipse", "plane", "extended", "nonlinear"],
)
def test_every_calibrator_is_guarded(sweep, make):
    _, frequency, readings = sweep
    start = time.perf_counter()
    with pytest.raises(wm.InputError, match="not resolved by the sweep") as info:
        make(50.0).fit(readings, frequency)
    assert time.perf_counter() - start < HANG_GUARD_S
    assert info.value.parameter == "fsr_hz"


def test_the_right_design_fits_exactly_as_before(sweep):
    """The guard only reads: a fit with the right design is the delay search's own."""
    device, frequency, readings = sweep
    cal = wm.Calibrator(50e9).fit(readings, frequency)
    search = cal.delay_search_
    assert cal.fsr_hz_ == 1 / search.delay_s
    estimate = cal.diagnostics_["fsr_estimate_hz"]
    # the estimate and the fit are both least-squares delays of the same cost
    assert estimate == pytest.approx(cal.fsr_hz_, abs=cal.summary()["fsr_hz"].stderr)


@pytest.mark.parametrize(
    "seed", [*range(3), *(pytest.param(seed, marks=pytest.mark.slow) for seed in range(3, 20))]
)
def test_partial_span_sweeps_are_not_refused(seed):
    """0.3 FSR: the periodogram cannot resolve the period, the cost J still does."""
    device = wm.Interferometer.table1(3, seed=seed)
    frequency = device.sweep_hz(600, span_fsr=0.3)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=seed)
    cal = wm.Calibrator(50e9).fit(readings, frequency)
    sigma = cal.summary()["fsr_hz"].stderr
    assert cal.fsr_hz_ == pytest.approx(device.true_fsr_hz, abs=5 * sigma)
    assert cal.diagnostics_["fsr_estimate_hz"] == pytest.approx(cal.fsr_hz_, abs=5 * sigma)


@pytest.mark.slow
@pytest.mark.parametrize("span_fsr", [0.3, 1.0, 20.0])
def test_the_estimate_finds_the_fringe_period(span_fsr):
    device = wm.Interferometer.table1(4, seed=3)
    frequency = device.sweep_hz(4000, span_fsr=span_fsr)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=3)
    shuffled = np.random.default_rng(0).permutation(frequency.size)  # any order will do
    estimate = estimate_fsr(readings[shuffled], frequency[shuffled])
    sigma = wm.Calibrator(50e9).fit(readings, frequency).summary()["fsr_hz"].stderr
    assert estimate.fsr_hz == pytest.approx(device.true_fsr_hz, abs=5 * sigma)
    assert estimate.explained > 0.999  # Table 1 noise is 2e-3 of the fringe amplitude


def test_readings_without_fringes_give_no_estimate():
    rng = np.random.default_rng(5)
    frequency = np.linspace(193.3e12, 193.4e12, 500)
    readings = 1e-3 + NOISE_W * rng.standard_normal((500, 3))
    assert estimate_fsr(readings, frequency) is None


def test_the_span_rule_names_the_estimate(sweep):
    device, frequency, readings = sweep
    with pytest.raises(wm.InputError, match="less than 0.1 of the FSR") as info:
        wm.Calibrator(5e12).fit(readings, frequency)
    assert suggested_fsr_hz(str(info.value)) == pytest.approx(device.true_fsr_hz, rel=1e-4)


def test_near_misses_are_left_to_the_search():
    """A true FSR just outside the bracket is the delay search's edge minimum, as before."""
    device = wm.Interferometer.ideal(3, fsr_hz=50e9)
    frequency = device.sweep_hz(201)
    with pytest.raises(wm.EdgeMinimumError):
        wm.Calibrator(fsr_hz=65e9, fsr_tolerance=0.1).fit(
            device.powers(frequency, POWER_W), frequency
        )


def test_nyquist_limit_of_the_guard():
    """Steps below half the smallest FSR searched pass; at or above it the sweep is refused."""
    frequency = 193.4e12 + np.arange(64) * 10e9
    assert median_step_hz(frequency) == pytest.approx(10e9)
    device = wm.Interferometer.ideal(3, fsr_hz=30e9)
    readings = device.powers(frequency, POWER_W)
    with warnings.catch_warnings():
        warnings.simplefilter("error", wm.CalibrationWarning)
        # smallest FSR searched 24 GHz: 10 GHz steps are below 12 GHz
        wm.Calibrator(30e9).fit(readings, frequency)
    with pytest.raises(wm.InputError, match="not resolved"):
        # smallest FSR searched 19.2 GHz: 10 GHz steps are not below 9.6 GHz
        wm.Calibrator(24e9).fit(readings, frequency)


def test_the_delay_grid_is_bounded_before_anything_is_evaluated():
    calls = []

    def cost(delay_s):
        calls.append(delay_s)
        return (delay_s * 50e9 - 1.0) ** 2

    span = 5000 * 50e9  # 5000 FSRs: +-20 % needs ~16,800 trial delays
    with pytest.raises(wm.InputError, match="narrow fsr_tolerance to at most") as info:
        search_delay(cost, fsr_hz=50e9, fsr_tolerance=0.2, span_hz=span)
    assert calls == [] and info.value.parameter == "fsr_tolerance"
    largest = float(re.search(r"at most ([0-9.e-]+)", str(info.value)).group(1))
    result = search_delay(cost, fsr_hz=50e9, fsr_tolerance=largest * 0.999, span_hz=span)
    assert len(result.grid_delay_s) <= MAX_GRID_POINTS
    assert result.delay_s == pytest.approx(1 / 50e9, rel=1e-9)


@pytest.mark.parametrize(
    ("convert", "named"),
    [
        (lambda f: f / 1e12, "frequencies in THz"),
        (lambda f: f / 1e9, "frequencies in GHz"),
        (lambda f: 299_792_458.0 / f * 1e9, "wavelengths in nm"),
    ],
    ids=["THz", "GHz", "nm"],
)
def test_a_frequency_axis_in_another_unit_is_named_as_such(sweep, convert, named):
    """Not an FSR advice in a nonsense unit (``set fsr_hz to about 0.05 Hz``): the unit."""
    _, frequency, readings = sweep
    with pytest.raises(wm.InputError, match=f"look like {named}: convert") as caught:
        wm.Calibrator(fsr_hz=50e9).fit(readings, convert(frequency))
    assert caught.value.parameter == "frequency_hz"
    assert "fsr_hz" not in str(caught.value)
