"""Method-specific checks of the baselines: ellipse geometry, power dependence, Kleijn's
fit and its convergence, and the reference-free fits on measured 3x3-coupler data."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.methods.baselines._labels import lock_phase
from wavemeter.calibration.methods.baselines.ellipse import (
    FringeEllipse,
    ellipse_phase,
    fit_conic,
    fit_ellipse,
)
from wavemeter.calibration.methods.baselines.nonlinear_fit import (
    NonlinearFitWarning,
    convergence_share,
    design_parameters,
)
from wavemeter.calibration.methods.baselines.plane_ellipse import (
    fit_plane_ellipse,
    plane_ellipse_phase,
)

POWER_W = 1e-3
NOISE_W = 5e-7
#: 30 ulp of a 193 THz frequency in float64: rounding only
NOISELESS_HZ = 1.0
MINIPTI = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "minipti-fiber-3x3"
#: agreement required with MiniPTI's published phase (rad rms)
MINIPTI_AGREEMENT_RAD = 10e-3

ELLIPSES = [  # center_x, center_y, amplitude_x, amplitude_y, phase_rad
    (3.1e-4, 2.6e-4, 2.9e-4, 3.3e-4, 2.0),  # a 3x3 port pair, W
    (1.64, 1.66, 1.49, 1.51, 2.15),  # MiniPTI-like, V
    (1e3, -5.0, 0.1, 3.0, 0.3),  # far off-centre, thin
    (0.0, 0.0, 1.0, 1.0, np.pi / 2),  # a circle
]


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def wrapped(phase_rad):
    return np.angle(np.exp(1j * np.asarray(phase_rad)))


def true_phase(device, frequency_hz):
    return 2 * np.pi * (np.asarray(frequency_hz) - device.center_hz) * device.delay_s


# ---------------------------------------------------------------------- ellipse geometry
@pytest.mark.parametrize("params", ELLIPSES)
def test_ellipse_fit_recovers_known_ellipse(params):
    truth = FringeEllipse(*params)
    t = np.linspace(-np.pi, np.pi, 50, endpoint=False)
    x = truth.center_x + truth.amplitude_x * np.cos(t)
    y = truth.center_y + truth.amplitude_y * np.cos(t - truth.phase_rad)
    fitted = fit_ellipse(x, y)
    scale = max(truth.amplitude_x, truth.amplitude_y)
    for name in ("center_x", "center_y", "amplitude_x", "amplitude_y"):
        assert abs(getattr(fitted, name) - getattr(truth, name)) <= 1e-10 * scale
    assert abs(fitted.phase_rad - truth.phase_rad) <= 1e-10
    assert np.max(np.abs(wrapped(ellipse_phase(fitted, x, y) - t))) <= 1e-10


@pytest.mark.parametrize("params", ELLIPSES)
def test_heydemann_phase_is_exact_on_an_ideal_ellipse(params):
    ellipse = FringeEllipse(*params)
    t = np.linspace(-np.pi, np.pi, 1001)[1:]
    x = ellipse.center_x + ellipse.amplitude_x * np.cos(t)
    y = ellipse.center_y + ellipse.amplitude_y * np.cos(t - ellipse.phase_rad)
    # rounding of the coordinates, relative to the amplitude, is all that is left
    offset = max(abs(ellipse.center_x) / ellipse.amplitude_x, 1.0)
    tolerance = 16 * np.finfo(float).eps * offset / np.sin(ellipse.phase_rad)
    assert np.max(np.abs(wrapped(ellipse_phase(ellipse, x, y) - t))) <= tolerance


def test_conic_fit_satisfies_the_constraint_and_the_points():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    x, y = 0.3 + 1.2 * np.cos(t), -0.2 + 0.7 * np.cos(t - 1.1)
    a, b, c, d, e, f = fit_conic(x, y)
    assert 4 * a * c - b * b == pytest.approx(1.0, rel=1e-12)
    algebraic = a * x * x + b * x * y + c * y * y + d * x + e * y + f
    assert np.max(np.abs(algebraic)) <= 1e-12


@pytest.mark.parametrize(
    ("x", "y", "message"),
    [
        ([0, 1, 2, 3], [1, 0, 1, 0], "at least 5 points, got 4"),
        ([0, 1, 2, 3, 4, 5], [0, 2, 4, 6, 8, 10], "do not trace an ellipse"),
        ([0, 1, np.nan, 3, 4], [0, 1, 2, 3, 4], "finite"),
    ],
)
def test_ellipse_fit_rejects_non_ellipses(x, y, message):
    with pytest.raises(ValueError, match=message):
        fit_ellipse(np.array(x, dtype=float), np.array(y, dtype=float))


def test_ellipse_calibrator_rejects_bad_ports():
    device = wm.Interferometer.ideal(3)
    f = device.sweep_hz(50)
    with pytest.raises(ValueError, match=r"ports must index the 3 port columns \(0..2\)"):
        wm.EllipseCalibrator(ports=(0, 3)).fit(device.powers(f), f)
    with pytest.raises(ValueError, match="two different port indices"):
        wm.EllipseCalibrator(ports=(1, 1)).fit(device.powers(f), f)


def test_lock_phase_recovers_direction_delay_and_origin():
    offset_hz = np.linspace(-20e9, 20e9, 101)
    delay_s = 1 / 52e9
    raw = wrapped(-(2 * np.pi * offset_hz * delay_s) + 0.7)  # decreasing, 0.7 rad at f0
    lock = lock_phase(raw, offset_hz, fsr_hz=50e9, span_hz=40e9)
    assert lock.direction == -1
    assert lock.delay_s == pytest.approx(delay_s, rel=1e-12)
    assert lock.origin_rad == pytest.approx(-0.7, abs=1e-12)
    assert lock.locking == pytest.approx(1.0, abs=1e-15)


# ---------------------------------------------------------------------- source power
def test_extended_conventional_degrades_with_source_power_as_predicted():
    """Todd's offsets are absolute: at ``k`` times the calibration power the quadratures are
    ``k [cos t, sin t] - (1 - k) W c``; the learned calibration is invariant."""
    device = wm.Interferometer.table1(3, seed=7)
    sweep_hz = device.sweep_hz(400)
    test_hz = device.center_hz + np.linspace(-0.5, 0.5, 2001)[:-1] * device.true_fsr_hz
    sweep = device.powers(sweep_hz, POWER_W)
    extended = wm.ExtendedConventionalCalibrator().fit(sweep, sweep_hz)
    learned = wm.Calibrator().fit(sweep, sweep_hz)
    ratio = 0.5
    test = device.powers(test_hz, ratio * POWER_W)

    matrix = device.true_map() * POWER_W  # the fringes at the calibration power
    weights = np.linalg.pinv(matrix[:, :2])
    offsets = np.sqrt(2) * matrix[:, 2]
    t = true_phase(device, test_hz)
    quadratures = ratio * np.column_stack([np.cos(t), np.sin(t)]) - (1 - ratio) * (
        weights @ offsets
    )
    expected_error_hz = wrapped(np.arctan2(quadratures[:, 1], quadratures[:, 0]) - t) * (
        device.true_fsr_hz / (2 * np.pi)
    )

    error_extended = wm.frequency_error_hz(extended.predict(test), test_hz, device.true_fsr_hz)
    error_learned = wm.frequency_error_hz(learned.predict(test), test_hz, device.true_fsr_hz)
    at_calibration_power = wm.frequency_error_hz(
        extended.predict(device.powers(test_hz, POWER_W)), test_hz, device.true_fsr_hz
    )
    assert np.max(np.abs(at_calibration_power)) <= NOISELESS_HZ
    assert np.max(np.abs(error_extended - expected_error_hz)) <= NOISELESS_HZ
    assert rms(expected_error_hz) > 100e6  # ~1 GHz for this device
    assert np.max(np.abs(error_learned)) <= NOISELESS_HZ


def test_extended_conventional_is_exact_on_an_ideal_device_at_any_power():
    """For an ideal device ``W c = 0``: equal offsets cancel in balanced quadratures."""
    device = wm.Interferometer.ideal(3)
    sweep_hz = device.sweep_hz(100)
    cal = wm.ExtendedConventionalCalibrator().fit(device.powers(sweep_hz, POWER_W), sweep_hz)
    test_hz = device.center_hz + np.linspace(-0.49, 0.49, 99) * device.true_fsr_hz
    error = wm.frequency_error_hz(
        cal.predict(device.powers(test_hz, 0.3 * POWER_W)), test_hz, device.true_fsr_hz
    )
    assert np.max(np.abs(error)) <= NOISELESS_HZ


def test_plane_ellipse_is_power_invariant_but_the_two_port_ellipse_is_not():
    device = wm.Interferometer.table1(3, seed=7)
    sweep_hz = device.sweep_hz(400)
    sweep = device.powers(sweep_hz, POWER_W)
    test_hz = device.center_hz + np.linspace(-0.5, 0.5, 1001)[:-1] * device.true_fsr_hz
    fluctuating = POWER_W * np.random.default_rng(3).uniform(0.3, 1.5, test_hz.size)
    test = device.powers(test_hz, fluctuating)
    plane = wm.PlaneEllipseCalibrator().fit(sweep, sweep_hz)
    pair = wm.EllipseCalibrator().fit(sweep, sweep_hz)
    plane_error = wm.frequency_error_hz(plane.predict(test), test_hz, device.true_fsr_hz)
    pair_error = wm.frequency_error_hz(pair.predict(test), test_hz, device.true_fsr_hz)
    assert np.max(np.abs(plane_error)) <= NOISELESS_HZ
    assert rms(pair_error) > 1e9  # the fixed ellipse cannot tell power from phase


def test_power_monitor_normalises_the_ellipse_calibration():
    device = wm.Interferometer.table1(3, seed=7)
    sweep_hz = device.sweep_hz(400)
    source_w = POWER_W * np.random.default_rng(4).uniform(0.8, 1.2, sweep_hz.size)
    sweep = device.powers(sweep_hz, source_w)
    test_hz = device.center_hz + np.linspace(-0.5, 0.5, 501)[:-1] * device.true_fsr_hz
    test = device.powers(test_hz, source_w.mean())
    for method in (wm.EllipseCalibrator, wm.PlaneEllipseCalibrator):
        cal = method().fit(sweep, sweep_hz, power_monitor_w=device.monitor(source_w))
        error = wm.frequency_error_hz(cal.predict(test), test_hz, device.true_fsr_hz)
        assert np.max(np.abs(error)) <= NOISELESS_HZ


# ---------------------------------------------------------------------- Kleijn's fit
def kleijn_parameters(device: wm.Interferometer) -> np.ndarray:
    """Kleijn's parameters of a device, per unit of the mean port sum (not exact if impaired)."""
    matrix = device.true_map()
    offsets, amplitudes = np.sqrt(2) * matrix[:, 2], np.hypot(matrix[:, 0], matrix[:, 1])
    total = offsets.sum()
    delayed = (np.sqrt(offsets + amplitudes) + np.sqrt(offsets - amplitudes)) / (2 * np.sqrt(total))
    other = (np.sqrt(offsets + amplitudes) - np.sqrt(offsets - amplitudes)) / (2 * np.sqrt(total))
    phases = np.arctan2(matrix[:, 1], matrix[:, 0])
    return np.concatenate([delayed, other, phases, [device.delay_s]])


def test_design_parameters_reproduce_an_ideal_device():
    """Ideal magnitudes and MMI phases; a Y-junction and zero bias add no common phase."""
    device = wm.Interferometer.ideal(3, splitter="y")
    f = device.sweep_hz(64)
    powers = device.powers(f, POWER_W)
    design = design_parameters(3, device.true_fsr_hz)
    delayed, other, phases = design[:3], design[3:6], design[6:9]
    t = true_phase(device, f)[:, None]
    model = powers.sum(axis=1, keepdims=True) * (
        delayed**2 + other**2 + 2 * delayed * other * np.cos(t - phases)
    )
    assert np.max(np.abs(model - powers)) <= 1e-15


def test_nonlinear_fit_converges_from_design_on_a_table1_device():
    device = wm.Interferometer.table1(3, seed=7)
    sweep_hz = device.sweep_hz(500)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=1)
    from_design = wm.NonlinearFitCalibrator().fit(sweep, sweep_hz)
    from_truth = wm.NonlinearFitCalibrator(initial=kleijn_parameters(device)).fit(sweep, sweep_hz)
    assert from_design.converged_ and from_design.fit_status_ in (1, 2, 3, 4)
    assert from_design.nfev_ < from_design.max_nfev
    # the same minimum as a start at the device's own parameters
    assert from_design.cost_ == pytest.approx(from_truth.cost_, rel=1e-9)
    assert from_design.fsr_hz_ == pytest.approx(from_truth.fsr_hz_, rel=1e-9)


def test_nonlinear_fit_is_exact_where_the_port_sum_is_the_source_power():
    """Splitter imbalance, arm loss, delay and bias keep the port sum flat: Kleijn's model is
    then exact, and without noise the fit reaches the learned method's machine precision."""
    device = dataclasses.replace(
        wm.Interferometer.ideal(3),
        splitter_amplitudes=np.array([0.62, 0.78j]),
        arm_loss_db=(1.0, 0.0),
        delay_s=1 / 51.5e9,
        bias_phase_rad=1.0,
    )
    sweep_hz = device.sweep_hz(300)
    sweep = device.powers(sweep_hz, POWER_W)
    test_hz = device.center_hz + np.linspace(-0.5, 0.5, 1001)[:-1] * device.true_fsr_hz
    test = device.powers(test_hz, POWER_W)
    for method in (wm.NonlinearFitCalibrator, wm.Calibrator):
        cal = method().fit(sweep, sweep_hz)
        error = wm.frequency_error_hz(cal.predict(test), test_hz, device.true_fsr_hz)
        assert np.max(np.abs(error)) <= NOISELESS_HZ


def test_nonlinear_fit_is_biased_by_the_port_sum_ripple_on_table1():
    """The paper's criticism: with Table 1 impairments the port sum moves with the phase,
    so even noiseless data leave Kleijn's fit above the noise limit of the learned method."""
    device = wm.Interferometer.table1(3, seed=7)
    sweep_hz = device.sweep_hz(500)
    test_hz = device.center_hz + np.linspace(-0.5, 0.5, 1001)[:-1] * device.true_fsr_hz
    port_sum = device.powers(test_hz, POWER_W).sum(axis=1)
    assert np.ptp(port_sum) / port_sum.mean() > 0.05  # the ripple the model ignores
    cal = wm.NonlinearFitCalibrator().fit(device.powers(sweep_hz, POWER_W), sweep_hz)
    error = wm.frequency_error_hz(
        cal.predict(device.powers(test_hz, POWER_W)), test_hz, device.true_fsr_hz
    )
    crlb = wm.crlb_frequency_std(
        device.true_map(), true_phase(device, test_hz), POWER_W, NOISE_W, device.true_fsr_hz
    )
    assert cal.converged_
    assert rms(error) > rms(crlb)


def test_nonlinear_fit_reports_non_convergence():
    device = wm.Interferometer.table1(3, seed=7)
    sweep_hz = device.sweep_hz(200)
    with pytest.warns(NonlinearFitWarning, match="did not converge"):
        cal = wm.NonlinearFitCalibrator(max_nfev=2).fit(device.powers(sweep_hz), sweep_hz)
    assert not cal.converged_
    assert cal.fit_status_ == 0
    assert "maximum number of function evaluations" in cal.fit_message_


@pytest.mark.parametrize(
    ("kwargs", "fit_kwargs", "message"),
    [
        ({"initial": [0.4] * 9}, {}, r"initial must be 3 n \+ 1 = 10 finite numbers"),
        ({"initial": [0.4] * 9 + [-1e-11]}, {}, "initial delay_s"),
        ({"max_nfev": 0}, {}, "max_nfev must be an integer >= 1, got 0"),
        ({}, {"power_monitor_w": 1e-5}, "power_monitor_w is not used by the nonlinear_fit"),
    ],
)
def test_nonlinear_fit_rejects_bad_settings(kwargs, fit_kwargs, message):
    device = wm.Interferometer.ideal(3)
    f = device.sweep_hz(50)
    with pytest.raises(ValueError, match=message):
        wm.NonlinearFitCalibrator(**kwargs).fit(device.powers(f), f, **fit_kwargs)


@pytest.mark.slow
def test_convergence_share_single_and_multi_fsr_sweeps():
    """Delay minima lie ``1 / K`` apart for a sweep of ``K`` FSRs: a one-FSR sweep has one
    basin, so every start within +-20 % converges; over 10 FSRs many starts fall into
    other basins, whose costs are far above the best."""
    device = wm.Interferometer.table1(3, seed=7)
    single_hz = device.sweep_hz(300)
    single = convergence_share(
        device.powers(single_hz, POWER_W, NOISE_W, rng=1), single_hz, starts=100, rng=5
    )
    assert single.share == 1.0
    assert single.initial.shape == (100, 10)
    assert np.all(np.abs(single.initial[:, :6] / design_parameters(3)[:6] - 1) <= 0.2)

    multi_hz = device.sweep_hz(1000, span_fsr=10)
    multi = convergence_share(
        device.powers(multi_hz, POWER_W, NOISE_W, rng=1), multi_hz, starts=20, rng=5
    )
    assert 0 < multi.share < 1
    assert np.all(multi.cost_w2[~multi.right] > 100 * multi.best_cost_w2)


# ---------------------------------------------------------------------- measured data
def read_columns(path: Path, names: list[str]) -> np.ndarray:
    with path.open(newline="") as handle:
        header = next(csv.reader(handle))
    columns = [header.index(name) for name in names]
    return np.loadtxt(path, delimiter=",", skiprows=1, usecols=columns, ndmin=2)


@pytest.fixture(scope="module")
def minipti():
    if not MINIPTI.is_dir():
        pytest.skip(f"measured MiniPTI data not found at {MINIPTI}")
    readings_v = read_columns(MINIPTI / "Decimation_Comercial.csv", ["DC CH1", "DC CH2", "DC CH3"])
    published = read_columns(MINIPTI / "PTI_Inversion_Comercial.csv", ["Interferometric Phase"])
    return readings_v, published[:, 0]


def agreement_rad(phase_rad, reference_rad) -> float:
    """RMS difference (rad) after the best sign and constant offset."""
    best = np.inf
    for sign in (1, -1):
        difference = wrapped(sign * phase_rad - reference_rad)
        offset = np.angle(np.mean(np.exp(1j * difference)))
        best = min(best, rms(wrapped(difference - offset)))
    return best


def test_plane_ellipse_matches_published_phase_on_measured_data(minipti):
    readings_v, published_rad = minipti
    assert readings_v.shape == (3726, 3)
    fit = fit_plane_ellipse(readings_v)
    assert agreement_rad(plane_ellipse_phase(fit, readings_v), published_rad) <= (
        MINIPTI_AGREEMENT_RAD
    )


def test_two_port_ellipse_matches_published_phase_on_measured_data(minipti):
    readings_v, published_rad = minipti
    x, y = readings_v[:, 0], readings_v[:, 1]
    phase = ellipse_phase(fit_ellipse(x, y), x, y)
    assert agreement_rad(phase, published_rad) <= MINIPTI_AGREEMENT_RAD
