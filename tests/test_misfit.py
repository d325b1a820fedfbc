"""Fit diagnostics (wavemeter.calibration.checks.misfit): clean sweeps pass, each fault is named.

Clean sweeps are in-model by construction (the simulator is the cone model plus white
noise), so every warning on them is a false alarm; the thresholds are 1e-6 per test, and
these tests check the statistics behind them (p-values, the model-free noise and its
standard error) on seeded sweeps. Each fault is simulated at a severity the tests below
detect with a wide margin, and must be named by its cause.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from scipy import stats

import wavemeter as wm
from wavemeter.calibration.checks.misfit import MisfitReport, misfit_report
from wavemeter.calibration.checks.misfit_causes import CAUSES
from wavemeter.calibration.models.learned_fit import fit_learned_map
from wavemeter.exceptions import CalibrationWarning, InputError
from wavemeter.simulation.drift import flicker_power_noise, slow_power_drift, thermal_ramp_rad
from wavemeter.stats import nested_tests
from wavemeter.stats.nested_tests import TEST_P_VALUE

POWER_W = 1e-3
NOISE_W = 5e-7  # Table 1
FSR_HZ = 50e9


def report_of(frequency_hz, powers_w, *, scale=None, affine=False, **options) -> MisfitReport:
    """Fit the learned map (centre = middle of the sweep) and report on its residual."""
    center = 0.5 * (frequency_hz.min() + frequency_hz.max())
    fit = fit_learned_map(
        powers_w,
        frequency_hz,
        center,
        fsr_hz=FSR_HZ,
        fsr_tolerance=0.2,
        scale=scale,
        affine=affine,
    )
    return misfit_report(
        powers_w, frequency_hz, center, fit.delay_s, fit.map_[:, :3], scale=scale, **options
    )


def sweep(device, samples, span_fsr=1.0, *, seed=1, power_w=POWER_W, noise_w=NOISE_W, **kw):
    frequency = device.sweep_hz(samples, span_fsr)
    return frequency, device.powers(frequency, power_w, noise_w, rng=seed, **kw)


def test_causes_are_the_issue_codes_in_order():
    assert CAUSES == (
        "power_drift",
        "detector_offset",
        "phase_drift",
        "dispersion",
        "partial_span",
        "unequal_noise",
        "ill_conditioned",
        "quantised_axis",
        "other_misfit",
    )


# ---------------------------------------------------------------------- clean sweeps
CLEAN_GRID = [
    (ports, samples, span, kind)
    for ports in (3, 4, 5)
    for samples in (8, 16, 64, 400)
    for span in (1.0, 3.0)
    for kind in ("table1", "ideal")
] + [(3, 2001, 1.0, "table1"), (4, 2001, 3.0, "table1")]


@pytest.fixture(scope="module")
def clean_reports() -> list[MisfitReport]:
    reports = []
    for index, (ports, samples, span, kind) in enumerate(CLEAN_GRID):
        if kind == "ideal":
            device = wm.Interferometer.ideal(ports)
        else:
            device = wm.Interferometer.table1(ports, seed=100 + index)
        frequency, powers = sweep(device, samples, span, seed=200 + index)
        reports.append(report_of(frequency, powers))
    return reports


@pytest.mark.slow
def test_clean_sweeps_do_not_warn(clean_reports):
    # 50 in-model sweeps, 3-5 ports, 8-2001 readings, 1 and 3 FSR, Table 1 and ideal:
    # with a false-alarm rate of 10 % all would pass with probability 0.005 (the rate
    # itself, <= 1 %, is measured over 200+ sweeps in benchmarks/misfit_false_alarms.py)
    warned = [
        (CLEAN_GRID[k], report.causes) for k, report in enumerate(clean_reports) if report.misfit
    ]
    assert warned == []


@pytest.mark.slow
def test_clean_p_values_are_not_too_small(clean_reports):
    """The null distributions behind the 1e-6 thresholds, checked at the 5 % level.

    Every reported p-value is valid (or conservative) under the model, so at most 5 % of
    them fall below 0.05 on average; the bound is the binomial 0.999 quantile (the tests of
    one sweep are nearly independent: different columns of the same residual).
    """
    p_values = np.array(
        [
            value
            for report in clean_reports
            for value in report.p_values.values()
            if value is not None
        ]
    )
    limit = stats.binom.isf(1e-3, p_values.size, 0.05)
    assert np.count_nonzero(p_values < 0.05) <= limit
    assert p_values.min() > TEST_P_VALUE


@pytest.mark.slow
def test_model_free_noise_within_its_standard_error(clean_reports):
    errors = []
    for report in clean_reports:
        if report.noise_method != "second_difference":
            continue
        # relative standard error of a standard deviation estimated on nu degrees of freedom
        standard_error = 1.0 / np.sqrt(2.0 * report.noise_dof)
        errors.extend((report.noise_std_w / NOISE_W - 1.0) / standard_error)
    errors = np.array(errors)
    assert errors.size >= 60
    assert np.all(np.abs(errors) < 4.5)
    # standardised errors: mean 0 and unit spread within their sampling error
    assert abs(errors.mean()) < 4.0 / np.sqrt(errors.size)
    spread = errors.std()
    bounds = np.sqrt(stats.chi2.ppf([1e-4, 1 - 1e-4], errors.size - 1) / (errors.size - 1))
    # 5 % more: the standard error is first order (delta method); nu is ~8 at 16 readings
    assert bounds[0] < spread < bounds[1] * 1.05


@pytest.mark.slow
def test_short_or_coarse_sweeps_use_the_residual_and_say_so(clean_reports):
    methods = {
        (samples, span): report.noise_method
        for (ports, samples, span, kind), report in zip(CLEAN_GRID, clean_reports, strict=True)
    }
    assert methods[(8, 1.0)] == methods[(16, 3.0)] == "residual"
    assert methods[(400, 1.0)] == methods[(64, 3.0)] == "second_difference"


def test_model_free_noise_ignores_a_slow_drift():
    device = wm.Interferometer.table1(3, seed=4)
    drift = slow_power_drift(2001, 0.2, rng=4)
    frequency, powers = sweep(device, 2001, power_w=POWER_W * drift, seed=5)
    report = report_of(frequency, powers)
    assert report.residual_rms_w.max() > 3 * NOISE_W  # the drift is in the residual
    standard_error = 1.0 / np.sqrt(2.0 * report.noise_dof)
    assert np.all(np.abs(report.noise_std_w / NOISE_W - 1.0) < 4.5 * standard_error)


def test_noiseless_sweep_fits_exactly_without_warning():
    device = wm.Interferometer.table1(4, seed=2)
    frequency, powers = sweep(device, 64, noise_w=0.0)
    report = report_of(frequency, powers)
    assert not report.misfit


# ---------------------------------------------------------------------- faults
def first_cause(report: MisfitReport) -> str:
    assert report.warnings, "the fault was not detected"
    return report.warnings[0].cause


@pytest.mark.slow
@pytest.mark.parametrize("span", [1.0, 3.0])
def test_slow_power_drift_is_power_drift(span):
    device = wm.Interferometer.table1(3, seed=6)
    drift = slow_power_drift(400, 0.5, rng=6)
    frequency, powers = sweep(device, 400, span, power_w=POWER_W * drift, seed=7)
    report = report_of(frequency, powers)
    assert first_cause(report) == "power_drift"
    message = str(report.warnings[0])
    assert "% RMS" in message and "power_monitor_w" in message
    # the drift the residual keeps, in % of the power (absorption takes part of it)
    assert 0.05 < report.power_error_rms < 0.5


def test_flicker_power_noise_is_power_drift():
    device = wm.Interferometer.table1(4, seed=8)
    flicker = flicker_power_noise(400, 0.01, rng=8)
    frequency, powers = sweep(device, 400, power_w=POWER_W * flicker, seed=9)
    assert first_cause(report_of(frequency, powers)) == "power_drift"


def test_cycling_thermostat_is_phase_drift():
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=10), thermal_phase_rad_per_k=1.0)
    samples = 400
    # 0.05 K peak to peak, three cycles over a three-FSR sweep
    temperature = device.reference_temperature_k + 0.025 * np.sin(
        2 * np.pi * 3 * np.arange(samples) / samples
    )
    frequency, powers = sweep(device, samples, 3.0, seed=11, temperature_k=temperature)
    report = report_of(frequency, powers)
    assert first_cause(report) == "phase_drift"
    assert "rad RMS" in str(report.warnings[0])
    assert 0.005 < report.phase_error_rms_rad < 0.05


def test_linear_ramp_is_invisible_one_way_and_seen_two_way():
    device = wm.Interferometer.table1(3, seed=12)
    one_way = device.sweep_hz(400)
    ramp = thermal_ramp_rad(400, 0.2, 1.0)  # 0.2 rad over the sweep: another FSR
    powers = device.powers(one_way, POWER_W, NOISE_W, rng=13, bias_drift_rad=ramp)
    assert not report_of(one_way, powers).misfit
    two_way = np.concatenate([one_way[::2], one_way[::-2]])
    powers = device.powers(two_way, POWER_W, NOISE_W, rng=13, bias_drift_rad=ramp)
    assert first_cause(report_of(two_way, powers)) == "phase_drift"


@pytest.mark.parametrize("dispersion_s2", [1e-25, 1e-24])
def test_group_delay_dispersion_is_dispersion(dispersion_s2):
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=14), dispersion_s2=dispersion_s2)
    frequency, powers = sweep(device, 1000, 10.0, seed=15)
    report = report_of(frequency, powers)
    assert first_cause(report) == "dispersion"
    assert "CalibrationSet" in str(report.warnings[0])


def test_detector_nonlinearity_is_other_misfit():
    device = wm.Interferometer.table1(3, seed=16)
    frequency, powers = sweep(device, 400, seed=17)
    compressed = powers - 0.01 * powers**2 / powers.max()  # 1 % compression at full scale
    assert first_cause(report_of(frequency, compressed)) == "other_misfit"


def offset_standard_errors(frequency, scale, delay_s, center_hz) -> np.ndarray:
    """Standard error (W) of fitted offsets: noise times sqrt of (X'X)^-1 at the offset."""
    phase = 2 * np.pi * (frequency - center_hz) * delay_s
    objects = np.column_stack(
        [scale * np.cos(phase), scale * np.sin(phase), scale * np.sqrt(2), np.ones_like(phase)]
    )
    return NOISE_W * np.sqrt(np.linalg.inv(objects.T @ objects)[3, 3])


def test_detector_offset_with_a_monitor_warns_unless_dark_given():
    dark = np.array([2e-5, -1e-5, 3e-5])  # 2-6 % of the mean readings
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=18), dark_offset_w=dark)
    power = POWER_W * slow_power_drift(400, 0.3, rng=18)
    frequency, powers = sweep(device, 400, power_w=power, seed=19)
    scale = power / power.mean()
    center = 0.5 * (frequency.min() + frequency.max())
    fit = fit_learned_map(
        powers, frequency, center, fsr_hz=FSR_HZ, fsr_tolerance=0.2, scale=scale, affine=True
    )
    offsets = fit.map_[:, 3]
    stderr = np.full(3, offset_standard_errors(frequency, scale, fit.delay_s, center))
    assert np.all(np.abs(offsets - dark) < 5 * stderr)
    common = (powers, frequency, center, fit.delay_s, fit.map_[:, :3])
    report = misfit_report(*common, scale=scale, offset_w=offsets, offset_std_w=stderr)
    assert report.causes == ("detector_offset",)
    message = str(report.warnings[0])
    assert "% of its mean reading" in message and "dark_w" in message
    dark_given = misfit_report(
        *common, scale=scale, offset_w=offsets, offset_std_w=stderr, dark_given=True
    )
    assert not dark_given.misfit
    assert report.to_dict()["offset_w"] == pytest.approx(offsets.tolist())


def test_constant_offset_without_monitor_is_absorbed():
    dark = np.array([2e-5, -1e-5, 3e-5])
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=20), dark_offset_w=dark)
    frequency, powers = sweep(device, 400, seed=21)
    assert not report_of(frequency, powers).misfit


def test_partial_span_warns_with_the_span():
    device = wm.Interferometer.table1(3, seed=22)
    frequency, powers = sweep(device, 200, 0.5, seed=23)
    report = report_of(frequency, powers)
    assert report.causes == ("partial_span",)
    assert report.span_fsr == pytest.approx(0.5, rel=0.01)
    assert "0.5" in str(report.warnings[0])


@pytest.mark.parametrize("samples", [8, 101, 2001])
def test_span_of_one_fsr_is_one(samples):
    device = wm.Interferometer.table1(3, seed=24)
    frequency, powers = sweep(device, samples, seed=25)
    report = misfit_report(
        powers, frequency, device.center_hz, device.delay_s, device.true_map() * POWER_W
    )
    assert report.span_fsr == pytest.approx(1.0, rel=1e-9)


def test_unequal_noise_warns_unless_the_retrieval_weights_ports():
    noise = np.array([5e-7, 5e-7, 1e-6])
    device = wm.Interferometer.table1(3, seed=26)
    frequency, powers = sweep(device, 400, noise_w=noise, seed=27)
    report = report_of(frequency, powers)
    assert report.causes == ("unequal_noise",)
    assert 'retrieval="ml"' in str(report.warnings[0])
    # each port's model-free noise is its own
    standard_error = 1.0 / np.sqrt(2.0 * report.noise_dof)
    assert np.all(np.abs(report.noise_std_w / noise - 1.0) < 4.5 * standard_error)
    assert not report_of(frequency, powers, weighted_retrieval=True).misfit


def test_weak_port_is_ill_conditioned_for_the_pseudo_inverse():
    ideal = wm.Interferometer.ideal(3)
    device = dataclasses.replace(ideal, responsivity=np.array([1.0, 1.0, 0.15]))
    frequency, powers = sweep(device, 400, seed=28)
    report = report_of(frequency, powers)
    assert report.causes == ("ill_conditioned",)
    assert report.pinv_variance_ratio > 1.44
    assert not report_of(frequency, powers, weighted_retrieval=True).misfit
    assert report_of(*sweep(ideal, 400, seed=28)).pinv_variance_ratio == pytest.approx(1.0)


# ---------------------------------------------------------------------- the report
def test_warnings_are_calibration_warnings_with_numbers_and_remedy():
    device = wm.Interferometer.table1(3, seed=30)
    drift = slow_power_drift(200, 0.2, rng=30)
    noise = np.array([5e-7, 5e-7, 2e-6])
    frequency, powers = sweep(device, 200, power_w=POWER_W * drift, noise_w=noise, seed=31)
    report = report_of(frequency, powers)
    assert report.causes == ("power_drift", "unequal_noise")
    for note in report.warnings:
        assert isinstance(note, CalibrationWarning) and isinstance(note, UserWarning)
        assert note.cause in CAUSES and note.remedy and str(note).endswith(note.remedy)
        assert any(char.isdigit() for char in str(note).replace(note.remedy, ""))


def test_to_dict_survives_json():
    device = wm.Interferometer.table1(4, seed=32)
    drift = slow_power_drift(200, 0.3, rng=32)
    frequency, powers = sweep(device, 200, power_w=POWER_W * drift, seed=33)
    report = report_of(frequency, powers)
    fields = report.to_dict()
    assert json.loads(json.dumps(fields, allow_nan=False)) == fields
    assert fields["misfit"] is True
    assert [w["cause"] for w in fields["warnings"]] == list(report.causes)
    assert set(fields["warnings"][0]) == {"cause", "message", "remedy"}
    assert len(fields["noise_ratio"]) == 4 and isinstance(fields["span_fsr"], float)
    for name in ("residual_rms_w", "noise_std_w", "lag1_autocorrelation", "harmonic_power"):
        assert all(isinstance(value, float) for value in fields[name])


@pytest.mark.parametrize(
    ("change", "parameter"),
    [
        ({"powers": np.ones(10)}, "powers"),
        ({"frequency_hz": np.ones(5)}, "frequency_hz"),
        ({"map_": np.ones((3, 4))}, "map_"),
        ({"delay_s": -1.0}, "delay_s"),
        ({"scale": np.ones(3)}, "scale"),
        ({"offset_w": np.zeros(3)}, "offset_std_w"),
    ],
)
def test_bad_inputs_raise_input_error(change, parameter):
    device = wm.Interferometer.table1(3, seed=34)
    frequency, powers = sweep(device, 32, seed=35)
    arguments = {
        "powers": powers,
        "frequency_hz": frequency,
        "center_hz": device.center_hz,
        "delay_s": device.delay_s,
        "map_": device.true_map() * POWER_W,
    }
    arguments.update(change)
    with pytest.raises(InputError) as caught:
        misfit_report(**arguments)
    assert caught.value.parameter == parameter


def test_monitored_power_drift_is_in_the_model():
    device = wm.Interferometer.table1(3, seed=36)
    power = POWER_W * slow_power_drift(400, 0.5, rng=36)
    frequency, powers = sweep(device, 400, power_w=power, seed=37)
    assert not report_of(frequency, powers, scale=power / power.mean()).misfit


def test_power_noise_on_a_short_sweep_is_power_drift():
    # 1 % flicker on 32 readings: the second differences count it as noise, but it moves
    # every reading along its own image direction A x only
    device = wm.Interferometer.table1(4, seed=38)
    flicker = flicker_power_noise(32, 0.01, rng=38)
    frequency, powers = sweep(device, 32, power_w=POWER_W * flicker, seed=39)
    report = report_of(frequency, powers)
    assert first_cause(report) == "power_drift"
    assert report.p_values["power_scatter"] < TEST_P_VALUE


def test_frequency_jitter_is_phase_drift():
    # the known frequencies are off by 200 MHz RMS (0.025 rad at 50 GHz) from reading to
    # reading: 20x the phase noise of one reading at the Table 1 noise
    device = wm.Interferometer.table1(3, seed=40)
    frequency = device.sweep_hz(100)
    jitter = np.random.default_rng(40).normal(0.0, 200e6, frequency.size)
    powers = device.powers(frequency + jitter, POWER_W, NOISE_W, rng=41)
    report = report_of(frequency, powers)
    assert first_cause(report) == "phase_drift"
    assert report.p_values["phase_scatter"] < TEST_P_VALUE


@pytest.mark.slow
@pytest.mark.parametrize("samples", [4, 5, 6])
def test_fewest_readings_do_not_warn(samples):
    # the harmonic and smooth columns can fill the whole residual space: no test then
    device = wm.Interferometer.table1(3, seed=42)
    for seed in range(5):
        frequency, powers = sweep(device, samples, seed=seed)
        assert not report_of(frequency, powers).misfit


# ---------------------------------------------------------------------- the computation
def p_values_of(report: MisfitReport) -> dict:
    return {name: value for name, value in report.p_values.items() if value is not None}


def test_cosines_through_dcts_give_the_statistics_of_the_formed_columns(monkeypatch):
    """The DCT route (``_CosineColumns``) and QR of the formed cosine columns are the same
    algebra in another order: they agree to rounding (1e-16 of statistics of up to ~1e3)
    amplified by the condition numbers of the column sets (below 1e2 here) and by the F
    tail's slope (``d ln p / d statistic`` ~ 1/2): 1e-9 relative leaves a wide margin."""
    device = wm.Interferometer.table1(4, seed=44)
    rng = np.random.default_rng(44)
    # frequencies not evenly spaced: no discrete cosine nearly coincides with the fringe (its
    # remainder after the fit, a tiny difference, would be known only to rounding / its size)
    frequency = np.sort(device.center_hz + device.true_fsr_hz * rng.uniform(-1.5, 1.5, 600))
    drift = slow_power_drift(600, 0.002, rng=44)
    powers = device.powers(frequency, POWER_W * drift, NOISE_W, rng=45)
    fast = report_of(frequency, powers)
    monkeypatch.setattr(nested_tests, "MIN_DCT_READINGS", 10**9)
    formed = report_of(frequency, powers)
    assert fast.causes == formed.causes == ("power_drift",)
    assert 0.0 < fast.p_values["power"] < TEST_P_VALUE  # a drift, p-values not underflowed
    assert p_values_of(fast) == pytest.approx(p_values_of(formed), rel=1e-9, abs=0.0)
    assert fast.power_error_rms == pytest.approx(formed.power_error_rms, rel=1e-9)
    assert fast.phase_error_rms_rad == pytest.approx(formed.phase_error_rms_rad, rel=1e-9)
    assert fast.harmonic_power == pytest.approx(formed.harmonic_power, rel=1e-9)


@pytest.mark.parametrize("samples", [64, 400])
def test_an_absorbed_cosine_is_left_out_whatever_the_rounding(samples):
    # with the true delay, cos t and sin t of readings evenly over one FSR span the discrete
    # cosine b_2 of the row: the smooth test leaves it out. Nudging the frequencies by 1 ulp
    # (2e-16, a phase change of ~5e-12 rad) moves the residual by ~1e-8 of the noise, so the
    # p-values may move by about as much, not by the direction rounding gives the remainder
    device = wm.Interferometer.table1(3, seed=46)
    frequency, powers = sweep(device, samples, seed=47)
    arguments = (device.center_hz, device.delay_s, device.true_map() * POWER_W)
    reference = p_values_of(misfit_report(powers, frequency, *arguments))
    rng = np.random.default_rng(46)
    for _ in range(3):
        nudged = frequency * (1.0 + 2e-16 * rng.standard_normal(samples))
        report = misfit_report(powers, nudged, *arguments)
        assert p_values_of(report) == pytest.approx(reference, rel=1e-6, abs=0.0)


def test_a_deep_power_dip_forms_the_cosine_columns(monkeypatch):
    # the source 1e10 times weaker over 15 % of a monitored sweep: the power and phase
    # columns vanish there and their Gram matrix is too ill-conditioned for the DCT route
    # (30 % errors in p-values, or no Cholesky factor, by the device): they are formed
    # (MIN_GRAM_WEIGHT), the same computation as with every cosine column formed
    device = wm.Interferometer.table1(3, seed=42)
    power = np.ones(1001)
    power[600:750] = 1e-10
    scale = power / power.mean()
    frequency, powers = sweep(device, 1001, power_w=POWER_W * scale, seed=43)
    report = report_of(frequency, powers, scale=scale)
    assert not report.misfit  # in the model
    monkeypatch.setattr(nested_tests, "MIN_DCT_READINGS", 10**9)
    formed = report_of(frequency, powers, scale=scale)
    for name in ("power", "phase"):
        assert report.p_values[name] == pytest.approx(formed.p_values[name], rel=1e-12)
    assert report.power_error_rms == pytest.approx(formed.power_error_rms, rel=1e-12)
    assert report.phase_error_rms_rad == pytest.approx(formed.phase_error_rms_rad, rel=1e-12)
