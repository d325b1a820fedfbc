"""The global delay search on sweeps over many FSRs: right minimum every time, edges caught.

A sweep over ``K`` FSRs gives ``J(tau)`` side minima about ``1/K`` apart in relative delay.
The tolerances come from physics: the fitted FSR is compared with its Cramer-Rao standard
deviation for the calibration sweep (Fisher information of ``tau`` with the ``3 n`` map
entries as nuisance parameters), the frequency errors with the per-reading CRLB.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import linalg

import wavemeter as wm
from wavemeter.calibration.delay_search import check_fringes_explained, search_delay
from wavemeter.calibration.learned import map_cost, object_vectors
from wavemeter.model.cone import cone_vectors, delay_phase_rad

from .conftest import NOISE_W, POWER_W

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


def fsr_crlb_std_hz(device: wm.Interferometer, frequency_hz: np.ndarray) -> float:
    """Cramer-Rao standard deviation (Hz) of the FSR fitted on a sweep, map unknown.

    Model ``p_k = A x(t_k)`` with ``t_k = 2 pi (f_k - f0) tau``; for each port the
    derivative by ``tau`` is projected off the span of the object vectors (the derivatives
    by that port's map row), ``var(tau) = sigma^2 / sum ||residual||^2``, and
    ``sigma_FSR = FSR^2 sigma_tau``.
    """
    offset = frequency_hz - device.center_hz
    phase = delay_phase_rad(frequency_hz, device.center_hz, device.delay_s)
    objects = cone_vectors(phase, POWER_W)
    tangent = np.stack([-np.sin(phase), np.cos(phase), np.zeros_like(phase)], axis=-1)
    derivative = (POWER_W * tangent @ device.true_map().T) * (2 * np.pi * offset)[:, None]
    q, _ = linalg.qr(objects, mode="economic")
    residual = derivative - q @ (q.T @ derivative)
    delay_std = NOISE_W / np.sqrt(np.sum(residual**2))
    return device.true_fsr_hz**2 * delay_std


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


def sweep_costs(relative_delay: float, span_fsr: int):
    device = device_with_delay(5, relative_delay)
    frequency = device.sweep_hz(200 * span_fsr, span_fsr=span_fsr)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=5)
    center = 0.5 * (frequency.min() + frequency.max())

    def cost(delay_s):
        return map_cost(object_vectors(frequency, center, delay_s), readings)[1]

    unfitted = float(np.sum(np.var(readings, axis=0)))
    return frequency, readings, cost, unfitted


@pytest.mark.parametrize("relative_delay", [0.82, 1.27])
@pytest.mark.parametrize("span_fsr", [1, 20])
def test_true_fsr_just_outside_the_bracket_is_an_edge_minimum(relative_delay, span_fsr):
    frequency, readings, *_ = sweep_costs(relative_delay, span_fsr)
    with pytest.raises(wm.EdgeMinimumError, match="edge of the FSR bracket.*fsr_tolerance"):
        wm.Calibrator(DESIGN_FSR_HZ, fsr_tolerance=TOLERANCE).fit(readings, frequency)


@pytest.mark.parametrize("relative_delay", [0.70, 1.50])
def test_true_fsr_far_outside_is_caught_by_the_unexplained_fringe_power(relative_delay):
    """Far outside the bracket a 20-FSR sweep has its best grid point on a side minimum."""
    _, _, cost, unfitted = sweep_costs(relative_delay, 20)
    options = {"fsr_hz": DESIGN_FSR_HZ, "fsr_tolerance": TOLERANCE, "span_hz": 20 * 50e9}
    side = search_delay(cost, **options)  # without the check: an interior side minimum
    assert 1 - side.cost / unfitted < 0.2
    with pytest.raises(wm.EdgeMinimumError, match="side minimum"):
        search_delay(cost, **options, unfitted_cost=unfitted)


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
