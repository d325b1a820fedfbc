"""Fit diagnostics of a wide-band model: per-reading maps, a design and phase derivatives.

The wide-band model of reading ``k`` is ``p_k = A(y_k) u(t_k)`` plus white detector noise,
with ``A(y) = sum_j A_j L_j(y)`` (Legendre series in ``y = (f - f0) / h``, ``h`` the half
span) and the phase polynomial ``t(y) = sum_i b_i y^i`` (``b_1 = 2 pi h tau``). Its map
coefficients are linear least squares on the design ``kron(L_j(y_k), u(t_k))`` shared by the
ports; its phase coefficients are shared by the ports, and either taken at their true values
or refitted by ``scipy.optimize.least_squares`` on the residual with the map projected out.
``misfit_report`` gets each reading's map, the phases, the design and ``dt_k / db_i = y_k^i``.

Sweeps are 20 FSRs of 50 GHz with 200 readings per FSR, 1 mW and the Table 1 noise (5e-7 W);
the map is a Table 1 device's with coefficients ``A_1``, ``A_2`` of 2 % of ``A_0``
(elementwise, random). In-model sweeps are in the model by construction: every warning on
them is a false alarm, and their p-values are checked at the 5 % level.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import optimize

import wavemeter as wm
from wavemeter.calibration.checks.misfit import MisfitReport, misfit_report
from wavemeter.exceptions import InputError
from wavemeter.simulation.drift import slow_power_drift
from wavemeter.stats import cosine_columns, nested_tests
from wavemeter.stats.nested_tests import TEST_P_VALUE
from wavemeter.stats.projection import Projector

from .helpers import (
    NOISE_W,
    POWER_W,
    QUADRATIC_PHASE_RAD,
    WidebandSweep,
    fit_map,
    narrow_band_case,
    wideband_report,
    wideband_sweep,
)
from .helpers import WIDEBAND_FSRS as FSRS
from .helpers import WIDEBAND_READINGS_PER_FSR as READINGS_PER_FSR

SWEEPS = 40
MISFIT_CAUSES = ("power_drift", "phase_drift", "dispersion", "other_misfit")


# ---------------------------------------------------------------------- the model
def fit_phase(sweep: WidebandSweep, degree: int, order: int) -> np.ndarray:
    """Phase coefficients ``b_1..b_order`` by least squares, the map projected out (variable
    projection), from the true ones off by 0.01 rad."""
    start = sweep.phase_coefficients_rad[:order] + 0.01
    solution = optimize.least_squares(
        lambda coefficients: fit_map(sweep, coefficients, degree)[3].ravel(), start, method="lm"
    )
    assert solution.success
    return solution.x


def first_cause(report: MisfitReport) -> str:
    assert report.warnings, "the fault was not detected"
    return report.warnings[0].cause


# ---------------------------------------------------------------------- today's reports
def assert_same_report(report: MisfitReport, reference: MisfitReport, rel: float) -> None:
    assert report.causes == reference.causes
    assert report.noise_method == reference.noise_method
    for field in dataclasses.fields(MisfitReport):
        value, expected = getattr(report, field.name), getattr(reference, field.name)
        if field.name == "p_values":
            assert value.keys() == expected.keys()
            for name, p_value in expected.items():
                assert value[name] == (None if p_value is None else pytest.approx(p_value, rel=rel))
        elif isinstance(expected, np.ndarray | float):
            assert value == pytest.approx(expected, rel=rel)


@pytest.mark.parametrize("kind", ["plain", "offsets", "phase"])
def test_todays_defaults_passed_explicitly_give_todays_report(kind):
    arguments, options, design, derivatives = narrow_band_case(kind)
    default = misfit_report(*arguments, **options)
    explicit = misfit_report(*arguments, **options, design=design, phase_derivatives=derivatives)
    assert_same_report(explicit, default, rel=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["plain", "offsets", "phase"])
def test_a_stack_of_identical_maps_is_the_single_map(kind):
    arguments, options, _, _ = narrow_band_case(kind)
    powers, frequency, center, delay, matrix = arguments
    single = misfit_report(*arguments, **options)
    stack = np.broadcast_to(matrix, (frequency.size, *matrix.shape))
    stacked = misfit_report(powers, frequency, center, delay, stack, **options)
    # the images differ by rounding (1e-16 of 1e-3 W) in a residual of 5e-7 W
    assert_same_report(stacked, single, rel=1e-12)


# ---------------------------------------------------------------------- in-model sweeps
@pytest.fixture(scope="module")
def in_model_reports() -> list[tuple[MisfitReport, MisfitReport]]:
    """For each sweep: the report at the true phase coefficients and at fitted ones."""
    reports = []
    for seed in range(SWEEPS):
        sweep = wideband_sweep(3 + seed % 2, 1000 + seed)
        true = wideband_report(sweep, sweep.phase_coefficients_rad, 2)
        fitted = wideband_report(sweep, fit_phase(sweep, 2, 2), 2)
        reports.append((true, fitted))
    return reports


@pytest.mark.slow
@pytest.mark.parametrize("which", [0, 1], ids=["true_phase", "fitted_phase"])
def test_in_model_wideband_sweeps_do_not_warn(in_model_reports, which):
    # tests at 1e-6 each: a false alarm among 40 sweeps has a probability below 4e-4
    warned = [(k, pair[which].causes) for k, pair in enumerate(in_model_reports)]
    assert [entry for entry in warned if entry[1]] == []


@pytest.mark.slow
@pytest.mark.parametrize("which", [0, 1], ids=["true_phase", "fitted_phase"])
def test_in_model_p_values_are_not_concentrated_near_zero(in_model_reports, which):
    """Each test's p-value is uniform (or conservative) under the model: below 0.05 in at
    most the binomial mean plus four standard deviations of the 40 sweeps (7; a uniform
    p-value exceeds it with probability 7e-4)."""
    limit = SWEEPS * 0.05 + 4.0 * np.sqrt(SWEEPS * 0.05 * 0.95)
    names = in_model_reports[0][which].p_values.keys()
    for name in names:
        made = [pair[which].p_values[name] for pair in in_model_reports]
        if all(p_value is None for p_value in made):
            continue  # a test made only on a misfit (band) or a rounded axis
        p_values = np.array(made)
        assert np.count_nonzero(p_values < 0.05) <= limit, name
        assert p_values.min() > TEST_P_VALUE, name


@pytest.mark.slow
def test_in_model_noise_is_the_detector_noise(in_model_reports):
    errors = []
    for true, _ in in_model_reports:
        assert true.noise_method == "second_difference"
        # relative standard error of a standard deviation estimated on nu degrees of freedom
        errors.extend((true.noise_std_w / NOISE_W - 1.0) * np.sqrt(2.0 * true.noise_dof))
    errors = np.array(errors)
    assert np.all(np.abs(errors) < 4.5)
    assert abs(errors.mean()) < 4.0 / np.sqrt(errors.size)


# ---------------------------------------------------------------------- out of the model
@pytest.mark.slow
@pytest.mark.parametrize(
    ("ports", "seed"),
    [
        (3, 60),
        pytest.param(4, 61, marks=pytest.mark.slow),
        pytest.param(4, 62, marks=pytest.mark.slow),
    ],
)
def test_unmodelled_cubic_phase_is_phase_drift(ports, seed):
    # b_3 = 0.02 rad: after the fitted b_1 y + b_2 y^2 a remainder 0.008 P_3(y) of 3e-3 rad
    # RMS, against a phase noise of ~1.4e-3 rad per reading (5e-7 W over a fringe tangent of
    # ~3.5e-4 W/rad): ~4000 (3e-3 / 1.4e-3)^2 = 2e4 in the score statistic, threshold ~100
    sweep = wideband_sweep(ports, seed, higher_phase_rad=(QUADRATIC_PHASE_RAD, 0.02))
    at_true = wideband_report(sweep, sweep.phase_coefficients_rad[:2], 2)
    assert first_cause(at_true) in ("phase_drift", "dispersion")
    # refitted, the degree-1 coefficient moves along the map's rotation with frequency (by up
    # to 0.4 rad): what is left can look like a power drift as well
    refitted = wideband_report(sweep, fit_phase(sweep, 2, 2), 2)
    assert first_cause(refitted) in MISFIT_CAUSES


@pytest.mark.slow
@pytest.mark.parametrize(("ports", "seed"), [(3, 63), (4, 64)])
def test_unmodelled_even_phase_is_dispersion(ports, seed):
    # b_4 = 0.02 rad (fit P = 2): its remainder after 1 and y^2 is (8/35) b_4 P_4(y), 1.5e-3
    # rad RMS (a score of ~4000 (1.5e-3 / 1.4e-3)^2 = 5e3), which the dispersion test's P_4
    # column takes; its P_2 column lies in the fitted directions
    sweep = wideband_sweep(ports, seed, higher_phase_rad=(QUADRATIC_PHASE_RAD, 0.0, 0.02))
    report = wideband_report(sweep, fit_phase(sweep, 2, 2), 2)
    assert first_cause(report) == "dispersion"
    assert report.p_values["dispersion"] < TEST_P_VALUE


@pytest.mark.slow
@pytest.mark.parametrize(("ports", "seed"), [(3, 65), (4, 66)])
def test_unmodelled_map_variation_warns(ports, seed):
    # the true map is quadratic in y, the fit linear: a residual P_2(y) A_2 u(t) of 3e-6 to
    # 4e-6 W RMS, 5-8 times the noise, a map polynomial in frequency on every port that no
    # common change of power or phase explains: the ports change each in its own way, which
    # is named dispersion (issue 29; it was power_drift or other_misfit)
    sweep = wideband_sweep(ports, seed, map_degree=2)
    report = wideband_report(sweep, fit_phase(sweep, 1, 2), 1)
    assert first_cause(report) == "dispersion"
    assert report.p_values["band_slope"] < TEST_P_VALUE
    assert "each in its own way" in str(report.warnings[0])


@pytest.mark.slow
@pytest.mark.parametrize(("ports", "seed"), [(3, 67), (4, 68)])
def test_unmodelled_power_drift_is_power_drift(ports, seed):
    # 0.5 % peak with five cycles over the sweep: not a polynomial of degree 2 in y, so the
    # map cannot absorb it; ~2e-6 W peak against the 5e-7 W noise, on 4000 readings
    drift = slow_power_drift(FSRS * READINGS_PER_FSR, 0.005, rng=seed, cycles=5.0)
    sweep = wideband_sweep(ports, seed, power=drift)
    report = wideband_report(sweep, fit_phase(sweep, 2, 2), 2)
    assert first_cause(report) == "power_drift"
    assert report.p_values["power"] < TEST_P_VALUE


# ---------------------------------------------------------------------- the computation
def test_projector_drops_a_coupled_direction_the_others_absorb():
    rng = np.random.default_rng(70)
    samples, ports = 300, 4
    basis = np.linalg.qr(rng.standard_normal((samples, 5)))[0]
    first, second = rng.standard_normal((2, samples, ports))
    inside = basis[:, :2] @ rng.standard_normal((2, ports))  # a fitted column on every port
    coupled = np.stack([first, inside, 2.0 * first - second, second], axis=2)
    projector = Projector(basis, coupled)
    directions = projector.directions.reshape(samples * ports, -1)
    # kept: first and 2 first - second; dropped: one in the fitted columns, one in the others
    assert projector.coupled.shape == (samples, ports, 2)
    assert projector.size == 5 * ports + 2
    gram = directions.T @ directions
    assert np.abs(gram - np.eye(gram.shape[0])).max() < 1e-12
    # every coupled column lies in the directions removed: the projection leaves rounding
    left = np.linalg.norm(projector(coupled), axis=(0, 1))
    assert np.all(left < 1e-12 * np.linalg.norm(coupled, axis=(0, 1)))


@pytest.mark.slow
def test_projected_directions_give_the_statistics_of_the_formed_ones(monkeypatch):
    """Directions applied through their structure (ProjectedCosineColumns) and cosine
    columns formed and factored by Householder QR are the same algebra in another order.
    With a phase polynomial of degree 3 a direction of the fit lies inside the phase test's
    span but for ~1e-8 of its norm (``y - y^3 / 3`` times the tangent: a cosine series
    converging as ``m^-4``), and is formed: any computation knows that remainder's
    direction to the rounding unit over its size, ~2e-8, which the residual's component
    along it carries into the statistics; 1e-7 of their size leaves a margin."""
    drift = slow_power_drift(FSRS * READINGS_PER_FSR, 0.0005, rng=71, cycles=5.0)
    sweep = wideband_sweep(4, 71, higher_phase_rad=(QUADRATIC_PHASE_RAD, 0.1), power=drift)
    coefficients = sweep.phase_coefficients_rad
    built = []
    original = cosine_columns.ProjectedCosineColumns.__init__

    def spy(self, *args):
        original(self, *args)
        built.append(self)

    monkeypatch.setattr(cosine_columns.ProjectedCosineColumns, "__init__", spy)
    monkeypatch.setattr(nested_tests, "MAX_FORMED_DIRECTIONS", 0)
    projected = wideband_report(sweep, coefficients, 2)
    assert len(built) == 2  # the power and phase tests
    assert sum(columns.frame.shape[1] for columns in built) >= 1
    monkeypatch.setattr(nested_tests, "MIN_DCT_READINGS", 10**9)
    formed = wideband_report(sweep, coefficients, 2)
    assert projected.causes == formed.causes == ("power_drift",)
    assert 0.0 < projected.p_values["power"] < TEST_P_VALUE  # a drift, not underflowed
    for name, p_value in formed.p_values.items():
        if p_value is None:  # a test not made (a rounded axis)
            assert projected.p_values[name] is None, name
            continue
        assert projected.p_values[name] == pytest.approx(p_value, rel=1e-7, abs=0.0), name
    assert projected.power_error_rms == pytest.approx(formed.power_error_rms, rel=1e-7)
    assert projected.phase_error_rms_rad == pytest.approx(formed.phase_error_rms_rad, rel=1e-7)


@pytest.mark.parametrize(
    ("change", "parameter"),
    [
        ({"map_": np.ones((11, 3, 3))}, "map_"),
        ({"map_": np.ones((40, 3, 2))}, "map_"),
        ({"map_": np.ones((40, 3))}, "map_"),
        ({"design": np.ones(40)}, "design"),
        ({"design": np.ones((39, 3))}, "design"),
        ({"design": np.ones((40, 0))}, "design"),
        ({"design": np.ones((40, 40))}, "design"),
        ({"design": np.full((40, 3), np.nan)}, "design"),
        ({"phase_derivatives": np.ones(40)}, "phase_derivatives"),
        ({"phase_derivatives": np.ones((2, 41))}, "phase_derivatives"),
        ({"phase_derivatives": np.ones((0, 40))}, "phase_derivatives"),
        ({"phase_derivatives": np.full((1, 40), np.inf)}, "phase_derivatives"),
    ],
)
def test_bad_shapes_raise_input_error_naming_the_parameter(change, parameter):
    device = wm.Interferometer.table1(3, seed=72)
    frequency = device.sweep_hz(40)
    arguments = {
        "powers": device.powers(frequency, POWER_W, NOISE_W, rng=73),
        "frequency_hz": frequency,
        "center_hz": device.center_hz,
        "delay_s": device.delay_s,
        "map_": device.true_map() * POWER_W,
    }
    arguments.update(change)
    with pytest.raises(InputError) as caught:
        misfit_report(**arguments)
    assert caught.value.parameter == parameter
    assert parameter in str(caught.value)
