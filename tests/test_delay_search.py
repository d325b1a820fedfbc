"""The global delay search on sweeps over many FSRs: right minimum every time, edges caught.

A sweep over ``K`` FSRs gives ``J(tau)`` side minima about ``1/K`` apart in relative delay.
The tolerances come from physics: the fitted FSR is compared with its Cramer-Rao standard
deviation for the calibration sweep (Fisher information of ``tau`` with the ``3 n`` map
entries as nuisance parameters), the frequency errors with the per-reading CRLB.

Edges (issue 9, item 7): a true FSR inside the bracket, however close to an edge, is
fitted; one outside is refused with the FSR where the cost is lowest; readings with no
fringe at all are told apart from a true FSR outside the bracket.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.checks.fsr_guard import estimate_fsr
from wavemeter.calibration.models.delay_search import (
    EDGE_POINTS,
    MAX_GRID_POINTS,
    check_fringes_explained,
    search_delay,
)
from wavemeter.calibration.models.linear_map import map_cost, object_vectors
from wavemeter.model.cone import delay_phase_rad

from .helpers import NOISE_W, POWER_W, fsr_crlb_std_hz

DESIGN_FSR_HZ = 50e9
TOLERANCE = 0.2
SPAN_FSR = 20
SWEEP_SAMPLES = 4000
TEST_SAMPLES = 2000
SEEDS = range(20)
MAX_FSR_Z = 4.0  # |fitted - true| / sigma; P(|z| > 4) = 6e-5 per seed
# RMS error / CRLB RMS: the pseudo-inverse + arctangent estimator is not exactly efficient
# for a non-orthogonal map (a few per cent above the bound for Table 1 devices) and the RMS
# of 2000 errors scatters by 1/sqrt(2 * 2000) = 1.6 % (5 sigma: 8 %).
CRLB_RATIO_RANGE = (0.92, 1.15)
GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


def device_with_delay(seed: int, relative_delay: float) -> wm.Interferometer:
    """A Table 1 3x3 device whose delay is ``relative_delay`` times the design delay."""
    device = wm.Interferometer.table1(3, seed=seed)
    return dataclasses.replace(device, delay_s=relative_delay / DESIGN_FSR_HZ)


def many_fsr_sweep(device: wm.Interferometer, seed: int) -> tuple[np.ndarray, np.ndarray]:
    frequency = device.sweep_hz(SWEEP_SAMPLES, span_fsr=SPAN_FSR)
    return frequency, device.powers(frequency, POWER_W, NOISE_W, rng=1000 + seed)


def crlb_rms_hz(device: wm.Interferometer, frequency_hz: np.ndarray) -> float:
    phase = delay_phase_rad(frequency_hz, device.center_hz, device.delay_s)
    bound = wm.crlb_frequency_std(device.true_map(), phase, POWER_W, NOISE_W, device.true_fsr_hz)
    return float(np.sqrt(np.mean(bound**2)))


def calibration_problems(seed: int, relative_delay: float) -> list[str]:
    """What is wrong with the calibration of one simulated 20-FSR sweep (empty if nothing)."""
    device = device_with_delay(seed, relative_delay)
    frequency, readings = many_fsr_sweep(device, seed)
    calibrator = wm.Calibrator(DESIGN_FSR_HZ, fsr_tolerance=TOLERANCE).fit(readings, frequency)
    problems = []
    z = (calibrator.fsr_hz_ - device.true_fsr_hz) / fsr_crlb_std_hz(device, frequency)
    if abs(z) > MAX_FSR_Z:
        problems.append(f"seed {seed}: fitted FSR {z:.1f} sigma from the truth")
    rng = np.random.default_rng(2000 + seed)
    half_span = SPAN_FSR * device.true_fsr_hz / 2
    test_hz = device.center_hz + rng.uniform(-half_span, half_span, TEST_SAMPLES)
    test = device.powers(test_hz, POWER_W, NOISE_W, rng)
    error = wm.frequency_error_hz(calibrator.predict(test), test_hz, device.true_fsr_hz)
    ratio = np.sqrt(np.mean(error**2)) / crlb_rms_hz(device, test_hz)
    ratio /= np.sqrt(1 + 3 / SWEEP_SAMPLES)
    if not CRLB_RATIO_RANGE[0] < ratio < CRLB_RATIO_RANGE[1]:
        problems.append(f"seed {seed}: RMS error {ratio:.3f} x CRLB")
    return problems


@pytest.mark.slow
@pytest.mark.parametrize(
    "delays",
    [
        pytest.param([1.08] * len(SEEDS), id="delay-8pc-long"),
        pytest.param(list(np.linspace(0.92, 1.08, len(SEEDS))), id="delay-spread-8pc"),
    ],
)
def test_twenty_fsr_sweeps_calibrate_on_every_seed(delays):
    problems = [text for seed in SEEDS for text in calibration_problems(seed, delays[seed])]
    assert problems == []


def textbook_golden_section(cost, low: float, high: float, xtol: float = 1e-12) -> float:
    """Golden-section search on [low, high] with no scan: the plain method of the paper."""
    a, b = low, high
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    cost_c, cost_d = cost(c), cost(d)
    while b - a > xtol * (abs(a) + abs(b)):
        if cost_c < cost_d:
            b, d, cost_d = d, c, cost_c
            c = b - GOLDEN * (b - a)
            cost_c = cost(c)
        else:
            a, c, cost_c = c, d, cost_d
            d = a + GOLDEN * (b - a)
            cost_d = cost(d)
    return 0.5 * (a + b)


@pytest.mark.slow
def test_plain_golden_search_lands_on_a_side_minimum_where_the_scan_does_not():
    """The teeth of the test above: without the scan, some of its sweeps are misfitted.

    Side minima of ``J`` get shallower away from the true delay, so golden section often
    follows the envelope (it does for every seed at +8 %), but not always.
    """
    wrong = []
    for seed, relative_delay in zip(SEEDS, np.linspace(0.92, 1.08, len(SEEDS)), strict=True):
        device = device_with_delay(seed, relative_delay)
        frequency, readings = many_fsr_sweep(device, seed)
        center = 0.5 * (frequency.min() + frequency.max())

        def cost(u, frequency=frequency, readings=readings, center=center):
            return map_cost(object_vectors(frequency, center, u / DESIGN_FSR_HZ), readings)[1]

        found = textbook_golden_section(cost, 1 / (1 + TOLERANCE), 1 / (1 - TOLERANCE))
        # one side-minimum spacing is 1/20 in relative delay; the true minimum is ~1e-6 wide
        if abs(found - relative_delay) > 1 / (4 * SPAN_FSR):
            wrong.append(seed)
    assert len(wrong) >= 1


def learned_cost(frequency: np.ndarray, readings: np.ndarray):
    """The learned map's cost ``J(tau)`` (W^2) on a sweep, phase origin at its middle."""
    center = 0.5 * (frequency.min() + frequency.max())

    def cost(delay_s):
        return map_cost(object_vectors(frequency, center, delay_s), readings)[1]

    return cost


def sweep_costs(relative_delay: float, span_fsr: int):
    device = device_with_delay(5, relative_delay)
    frequency = device.sweep_hz(200 * span_fsr, span_fsr=span_fsr)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=5)
    unfitted = float(np.sum(np.var(readings, axis=0)))
    return frequency, readings, learned_cost(frequency, readings), unfitted


def printed_hz(pattern: str, message: str) -> float:
    """The frequency (Hz) a message prints in GHz after ``pattern``."""
    return float(re.search(pattern + r" ([0-9.]+) GHz", message).group(1)) * 1e9


def printed_rounding(value: float, digits: int = 6) -> float:
    """Half a unit in the last of ``digits`` significant digits: the precision of a print
    (6 for frequencies, 3 for percentages and ratios)."""
    return 0.5 * 10.0 ** (np.floor(np.log10(abs(value))) - digits + 1)


@pytest.mark.slow
@pytest.mark.parametrize("relative_delay", [0.82, 1.27])
@pytest.mark.parametrize("span_fsr", [1, 20])
def test_true_fsr_just_outside_the_bracket_is_an_edge_minimum(relative_delay, span_fsr):
    """1.6 % outside: refused, naming the true FSR to its standard error (not the edge).

    Four standard errors and the print's rounding are far below the scan step, which is
    all the brief asks ("within a grid step").
    """
    frequency, readings, *_ = sweep_costs(relative_delay, span_fsr)
    with pytest.raises(wm.EdgeMinimumError, match="edge of the FSR bracket.*fsr_tolerance") as info:
        wm.Calibrator(DESIGN_FSR_HZ, fsr_tolerance=TOLERANCE).fit(readings, frequency)
    message = str(info.value)
    assert "40 GHz to 60 GHz" in message and "widen fsr_tolerance or correct fsr_hz" in message
    device = device_with_delay(5, relative_delay)
    reported = printed_hz("best at an FSR of", message)
    sigma = fsr_crlb_std_hz(device, frequency)
    tolerance = MAX_FSR_Z * sigma + printed_rounding(reported)
    assert reported == pytest.approx(device.true_fsr_hz, abs=tolerance)


def near_edge_fsr_hz(edge: str, inside: float) -> float:
    """An FSR inside the bracket, ``inside`` (relative) from its lowest or highest FSR."""
    if edge == "lowest":
        return DESIGN_FSR_HZ * (1 - TOLERANCE) * (1 + inside)
    return DESIGN_FSR_HZ * (1 + TOLERANCE) / (1 + inside)


@pytest.mark.slow
@pytest.mark.parametrize("inside", [0.005, 0.001])
@pytest.mark.parametrize("edge", ["lowest", "highest"])
@pytest.mark.parametrize(
    "span_fsr", [1, *(pytest.param(span, marks=pytest.mark.slow) for span in (3, 20))]
)
def test_true_fsr_near_an_edge_is_fitted_not_refused(span_fsr, edge, inside):
    """0.5 % and 0.1 % inside an edge, with Table 1 noise: fitted to the Cramer-Rao bound.

    Through :func:`search_delay` with the fringe check on three seeds, and through the
    public calibrator on the first (its fit diagnostics take seconds on 20 FSRs). Before
    the edge points every one of these was refused for 1 and 3 FSRs, and at 0.1 % for 20
    FSRs. The margin to the edge is >= 16 standard errors of the FSR.
    """
    problems = []
    for seed in range(3):
        device = dataclasses.replace(
            wm.Interferometer.table1(3, seed=seed), delay_s=1 / near_edge_fsr_hz(edge, inside)
        )
        frequency = device.sweep_hz(200 * span_fsr, span_fsr=span_fsr)
        readings = device.powers(frequency, POWER_W, NOISE_W, rng=3000 + seed)
        result = search_delay(
            learned_cost(frequency, readings),
            fsr_hz=DESIGN_FSR_HZ,
            fsr_tolerance=TOLERANCE,
            span_hz=float(np.ptp(frequency)),
            unfitted_cost=float(np.sum(np.var(readings, axis=0))),
        )
        fitted = {"search": 1 / result.delay_s}
        if seed == 0:
            calibrator = wm.Calibrator(DESIGN_FSR_HZ, fsr_tolerance=TOLERANCE)
            fitted["calibrator"] = calibrator.fit(readings, frequency).fsr_hz_
        sigma = fsr_crlb_std_hz(device, frequency)
        for name, fsr_hz in fitted.items():
            z = (fsr_hz - device.true_fsr_hz) / sigma
            if abs(z) > MAX_FSR_Z:
                problems.append(f"seed {seed}, {name}: FSR {z:.1f} sigma from the truth")
    assert problems == []


def parabola(minimum: float, calls: list):
    """A cost ``(u - minimum)^2`` of the relative delay ``u``, recording where it is called."""

    def cost(delay_s: float) -> float:
        calls.append(delay_s * DESIGN_FSR_HZ)
        return (delay_s * DESIGN_FSR_HZ - minimum) ** 2

    return cost


BRACKET = (1 / (1 + TOLERANCE), 1 / (1 - TOLERANCE))  # relative delays
# scan step in relative delay for a 20-FSR sweep: at most 1/(8 K), the bracket's ends on the grid
STEP = (BRACKET[1] - BRACKET[0]) / np.ceil((BRACKET[1] - BRACKET[0]) * 8 * SPAN_FSR)
PARABOLA_OPTIONS = {"fsr_hz": DESIGN_FSR_HZ, "fsr_tolerance": TOLERANCE, "span_hz": 20 * 50e9}


@pytest.mark.parametrize("method", ["golden", "brent"])
@pytest.mark.parametrize("end", [0, 1])
def test_the_bracket_is_closed_to_the_refinement_precision(method, end):
    """A minimum 1e-9 inside an edge is accepted, 1e-9 outside refused (xtol is 1e-12)."""
    edge = BRACKET[end]
    for offset, accepted in ((-1e-9, True), (1e-9, False)):
        minimum = edge * (1 + offset) if end else edge * (1 - offset)
        calls = []
        if accepted:
            result = search_delay(parabola(minimum, calls), **PARABOLA_OPTIONS, method=method)
            assert result.delay_s * DESIGN_FSR_HZ == pytest.approx(minimum, rel=1e-11)
            assert result.evaluations == len(calls)
        else:
            with pytest.raises(wm.EdgeMinimumError, match="is best at an FSR of") as info:
                search_delay(parabola(minimum, calls), **PARABOLA_OPTIONS, method=method)
            reported = printed_hz("best at an FSR of", str(info.value))
            fsr = DESIGN_FSR_HZ / minimum
            assert reported == pytest.approx(fsr, abs=printed_rounding(fsr))
        # the cost is evaluated only on the scan: the bracket and EDGE_POINTS beyond it
        assert BRACKET[0] - EDGE_POINTS * STEP <= min(calls)
        assert max(calls) <= BRACKET[1] + EDGE_POINTS * STEP


def test_a_minimum_inside_is_refined_inside_with_no_edge_points():
    calls = []
    result = search_delay(parabola(1.0, calls), **PARABOLA_OPTIONS)
    assert BRACKET[0] <= min(calls) and max(calls) <= BRACKET[1]
    assert result.delay_s == pytest.approx(1 / DESIGN_FSR_HZ, rel=1e-11)
    assert result.evaluations == len(calls)
    assert result.grid_delay_s.size == 1 + round((BRACKET[1] - BRACKET[0]) / STEP)


@pytest.mark.parametrize("minimum", [0.5, 2.0])
def test_a_minimum_beyond_the_edge_points_names_the_end_of_the_scan(minimum):
    """The scan stops EDGE_POINTS steps beyond the edge; the error names that FSR."""
    calls = []
    with pytest.raises(wm.EdgeMinimumError, match="last delay scanned.*at or beyond") as info:
        search_delay(parabola(minimum, calls), **PARABOLA_OPTIONS)
    last = BRACKET[0] - EDGE_POINTS * STEP if minimum < 1 else BRACKET[1] + EDGE_POINTS * STEP
    reported = printed_hz("at an FSR of", str(info.value))
    assert reported == pytest.approx(DESIGN_FSR_HZ / last, abs=printed_rounding(reported))
    assert min(calls) >= BRACKET[0] - EDGE_POINTS * STEP - 1e-12
    assert max(calls) <= BRACKET[1] + EDGE_POINTS * STEP + 1e-12


def test_delays_below_the_bracket_stay_positive():
    """+-90 % on half an FSR: the scan step is 1/4 of the design delay, so beyond the low
    end (u = 1/1.9) only one step fits above half of it."""
    calls = []
    options = {"fsr_hz": DESIGN_FSR_HZ, "fsr_tolerance": 0.9, "span_hz": 0.5 * DESIGN_FSR_HZ}
    with pytest.raises(wm.EdgeMinimumError, match="last delay scanned"):
        search_delay(parabola(0.01, calls), **options)
    assert min(calls) >= 0.5 / 1.9


def test_edge_points_count_against_the_grid_limit():
    """The largest tolerance the refusal prints is allowed, and its scan with the edge
    points beyond it stays within MAX_GRID_POINTS."""
    calls = []
    span = 1000 * DESIGN_FSR_HZ
    with pytest.raises(wm.InputError, match="at most ([0-9.e-]+)") as info:
        search_delay(parabola(2.0, calls), fsr_hz=DESIGN_FSR_HZ, fsr_tolerance=0.4, span_hz=span)
    assert calls == []
    largest = float(re.search(r"at most ([0-9.e-]+)", str(info.value)).group(1))
    with pytest.raises(wm.EdgeMinimumError, match="last delay scanned"):
        search_delay(
            parabola(2.0, calls), fsr_hz=DESIGN_FSR_HZ, fsr_tolerance=largest, span_hz=span
        )
    assert len(calls) <= MAX_GRID_POINTS
    assert sum(u > 1 / (1 - largest) for u in calls) == EDGE_POINTS


@pytest.mark.parametrize("relative_delay", [0.70, 1.50])
@pytest.mark.parametrize("span_fsr", [1, 3])
def test_true_fsr_far_outside_a_short_sweep_names_where_the_cost_falls(relative_delay, span_fsr):
    """On 1-3 FSRs the main minimum is wide: the cost falls all the way to the scan's end."""
    frequency, readings, *_ = sweep_costs(relative_delay, span_fsr)
    with pytest.raises(wm.EdgeMinimumError, match="last delay scanned.*at or beyond") as info:
        wm.Calibrator(DESIGN_FSR_HZ, fsr_tolerance=TOLERANCE).fit(readings, frequency)
    reported = printed_hz("at an FSR of", str(info.value))
    true_fsr_hz = DESIGN_FSR_HZ / relative_delay
    edge_hz = DESIGN_FSR_HZ * (1 + TOLERANCE if relative_delay < 1 else 1 - TOLERANCE)
    assert min(edge_hz, true_fsr_hz) < reported < max(edge_hz, true_fsr_hz)


@pytest.mark.parametrize("relative_delay", [0.70, 1.50])
def test_true_fsr_far_outside_is_caught_by_the_unexplained_fringe_power(relative_delay):
    """Far outside the bracket a 20-FSR sweep has its best grid point on a side minimum."""
    _, _, cost, unfitted = sweep_costs(relative_delay, 20)
    options = {"fsr_hz": DESIGN_FSR_HZ, "fsr_tolerance": TOLERANCE, "span_hz": 20 * 50e9}
    side = search_delay(cost, **options)  # without the check: an interior side minimum
    assert 1 - side.cost / unfitted < 0.2
    with pytest.raises(wm.EdgeMinimumError, match="side minimum"):
        search_delay(cost, **options, unfitted_cost=unfitted)


def number_after(pattern: str, message: str) -> float:
    return float(re.search(pattern + r" ([0-9.e+-]+)", message).group(1))


@pytest.mark.parametrize("relative_delay", [0.70, 1.50])
def test_a_side_minimum_of_strong_fringes_names_that_cause(relative_delay):
    """With the noise-only cost: fringes 1e6 times the noise power, so the FSR is wrong."""
    _, readings, cost, unfitted = sweep_costs(relative_delay, 20)
    options = {"fsr_hz": DESIGN_FSR_HZ, "fsr_tolerance": TOLERANCE, "span_hz": 20 * 50e9}
    side = search_delay(cost, **options)
    noise_cost = readings.shape[1] * NOISE_W**2
    with pytest.raises(wm.EdgeMinimumError, match="side minimum, while the readings carry") as info:
        search_delay(cost, **options, unfitted_cost=unfitted, noise_cost=noise_cost)
    message = str(info.value)
    assert "widen fsr_tolerance or correct fsr_hz" in message
    explained = 100 * (1 - side.cost / unfitted)
    assert number_after("explains only", message) == pytest.approx(
        explained, abs=printed_rounding(explained, 3)
    )
    ratio = unfitted / noise_cost
    assert number_after("about the mean is", message) == pytest.approx(
        ratio, abs=printed_rounding(ratio, 3)
    )
    fsr = 1 / side.delay_s
    assert printed_hz("at an FSR of", message) == pytest.approx(fsr, abs=printed_rounding(fsr))


def fringeless_sweep(seed: int):
    """Readings of a source that never reaches the interferometer: offsets and noise."""
    frequency = device_with_delay(seed, 1.0).sweep_hz(4000, span_fsr=20)
    rng = np.random.default_rng(seed)
    readings = POWER_W * np.array([0.3, 0.3, 0.4]) + NOISE_W * rng.standard_normal((4000, 3))
    unfitted = float(np.sum(np.var(readings, axis=0)))
    return frequency, readings, learned_cost(frequency, readings), unfitted


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(3))
def test_readings_without_fringes_are_not_blamed_on_the_fsr(seed):
    """Unfitted cost ~ noise cost (chi^2 scatter 1.3 %, the threshold is a factor 2)."""
    _, readings, cost, unfitted = fringeless_sweep(seed)
    options = {"fsr_hz": DESIGN_FSR_HZ, "fsr_tolerance": TOLERANCE, "span_hz": 20 * 50e9}
    noise_cost = readings.shape[1] * NOISE_W**2
    with pytest.raises(wm.InputError, match="carry no fringe above the noise") as info:
        search_delay(cost, **options, unfitted_cost=unfitted, noise_cost=noise_cost)
    assert not isinstance(info.value, wm.EdgeMinimumError)
    assert info.value.parameter == "powers"
    assert "widen" not in str(info.value) and "side minimum" not in str(info.value)
    assert number_after("only", str(info.value)) == pytest.approx(1.0, abs=0.05)
    # callers that do not give the noise-only cost get the undecided message of before
    with pytest.raises(wm.EdgeMinimumError, match="side minimum.*or the readings carry no"):
        search_delay(cost, **options, unfitted_cost=unfitted)


@pytest.mark.parametrize("fringes", [True, False])
def test_the_sweeps_own_fringe_gives_the_noise_only_cost(fringes):
    """The wiring proposed for the calibrator: ``noise_cost`` from :func:`estimate_fsr`.

    The lowest cost at any delay is what noise alone leaves; with no fringe anywhere
    (no estimate) the readings' own variation is the best noise figure there is.
    """
    if fringes:
        frequency, readings, cost, unfitted = sweep_costs(0.70, 20)
        expected = (wm.EdgeMinimumError, "side minimum, while the readings carry fringes")
    else:
        frequency, readings, cost, unfitted = fringeless_sweep(0)
        expected = (wm.InputError, "carry no fringe above the noise")
    estimate = estimate_fsr(readings, frequency)
    assert (estimate is not None) == fringes
    noise_cost = unfitted if estimate is None else unfitted * (1 - estimate.explained)
    options = {"fsr_hz": DESIGN_FSR_HZ, "fsr_tolerance": TOLERANCE, "span_hz": 20 * 50e9}
    with pytest.raises(expected[0], match=expected[1]):
        search_delay(cost, **options, unfitted_cost=unfitted, noise_cost=noise_cost)


def test_fringe_check_passes_the_true_minimum():
    _, _, cost, unfitted = sweep_costs(1.08, 20)
    result = search_delay(
        cost,
        fsr_hz=DESIGN_FSR_HZ,
        fsr_tolerance=TOLERANCE,
        span_hz=20 * 50e9,
        unfitted_cost=unfitted,
    )
    # the fit leaves only the noise: J = n sigma^2 (1 - (3 n + 1) / (N n)), chi^2 scatter 1.3 %
    samples, ports = 20 * 200, 3
    expected = ports * NOISE_W**2 * (1 - (3 * ports + 1) / (samples * ports))
    assert result.cost == pytest.approx(expected, rel=0.07)
    assert result.delay_s == pytest.approx(1.08 / DESIGN_FSR_HZ, rel=1e-5)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_fringe_check_rejects_a_meaningless_reference(bad):
    with pytest.raises(ValueError, match="unfitted_cost must be > 0"):
        check_fringes_explained(1.0, bad, fsr_hz=DESIGN_FSR_HZ, fsr_tolerance=TOLERANCE)
    with pytest.raises(wm.InputError, match="noise_cost must be a finite number > 0") as info:
        check_fringes_explained(
            1.0, 2.0, fsr_hz=DESIGN_FSR_HZ, fsr_tolerance=TOLERANCE, noise_cost=bad
        )
    assert info.value.parameter == "noise_cost"
