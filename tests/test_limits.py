"""The Cramer-Rao bound: reference values, an independent Fisher matrix, Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.exceptions import InputError

from .helpers import NOISE_W, POWER_W, random_test_frequencies


@pytest.mark.parametrize(("ports", "expected_mhz"), [(3, 9.75), (4, 11.25)])
def test_ideal_reference_values(ports, expected_mhz):
    closed = wm.crlb_ideal_frequency_std(ports, POWER_W, NOISE_W, 50e9)
    assert round(closed / 1e6, 2) == expected_mhz
    device = wm.Interferometer.ideal(ports)
    t = np.linspace(-np.pi, np.pi, 97)
    per_sample = wm.crlb_frequency_std(device.true_map(), t, POWER_W, NOISE_W, 50e9)
    np.testing.assert_allclose(per_sample, closed, rtol=1e-12)


def _fisher_bound(matrix, t, power, sigma, fsr_hz, step=1e-6):
    """Bound from a finite-difference Fisher matrix of p(t, P) = P A x(t), inverted.

    ``sigma`` is one noise for all ports or one per port (weights ``1 / sigma_j^2``).
    """

    def model(theta, p):
        return p * matrix @ np.array([np.cos(theta), np.sin(theta), np.sqrt(2)])

    d_t = (model(t + step, power) - model(t - step, power)) / (2 * step)
    d_p = (model(t, power * (1 + step)) - model(t, power * (1 - step))) / (2 * step * power)
    jacobian = np.column_stack([d_t, d_p])
    weight = np.broadcast_to(1 / np.square(sigma), matrix.shape[:1])
    covariance = np.linalg.inv(jacobian.T @ (weight[:, None] * jacobian))
    return fsr_hz * np.sqrt(covariance[0, 0]) / (2 * np.pi)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_formula_matches_an_independent_fisher_matrix(seed):
    device = wm.Interferometer.table1(4, seed=seed)
    matrix = device.true_map()
    for t in np.linspace(-3, 3, 7):
        expected = _fisher_bound(matrix, t, POWER_W, NOISE_W, device.true_fsr_hz)
        got = wm.crlb_frequency_std(matrix, t, POWER_W, NOISE_W, device.true_fsr_hz)
        assert got == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("seed", [0, 1])
def test_per_port_noise_matches_an_independent_fisher_matrix(seed):
    device = wm.Interferometer.table1(4, seed=seed)
    matrix = device.true_map()
    noise = NOISE_W * np.array([1.0, 3.0, 0.5, 1.0])
    for t in np.linspace(-3, 3, 7):
        expected = _fisher_bound(matrix, t, POWER_W, noise, device.true_fsr_hz)
        got = wm.crlb_frequency_std(matrix, t, POWER_W, noise, device.true_fsr_hz)
        assert got == pytest.approx(expected, rel=1e-6)


def test_per_port_noise_reduces_to_one_noise():
    """Equal per-port noise gives the one-noise bound; one noise is computed as before."""
    matrix = wm.Interferometer.table1(3, seed=4).true_map()
    t = np.linspace(-np.pi, np.pi, 33)
    power = POWER_W * np.linspace(0.5, 2, 33)
    scalar = wm.crlb_frequency_std(matrix, t, power, NOISE_W, 50e9)
    per_port = wm.crlb_frequency_std(matrix, t, power, np.full(3, NOISE_W), 50e9)
    np.testing.assert_allclose(per_port, scalar, rtol=1e-12)
    # the formula of 0.1, term for term: one noise must give bit-identical results
    zeros = np.zeros_like(t)
    a_t = np.stack([-np.sin(t), np.cos(t), zeros], axis=-1) @ matrix.T * power[..., None]
    a_p = np.stack([np.cos(t), np.sin(t), zeros + np.sqrt(2.0)], axis=-1) @ matrix.T
    along = np.einsum("...i,...i->...", a_t, a_p)
    information = (
        np.einsum("...i,...i->...", a_t, a_t) - along**2 / np.einsum("...i,...i->...", a_p, a_p)
    ) / NOISE_W**2
    np.testing.assert_array_equal(scalar, 50e9 / (2.0 * np.pi * np.sqrt(information)))


@pytest.mark.slow
@pytest.mark.parametrize("ports", [3, 4])
def test_monte_carlo_of_ideal_retrieval_meets_the_bound(ports):
    """RMS error of calibrate-then-retrieve on an ideal device equals the bound within 2 %.

    Expected RMS: CRLB * sqrt(1 + 3/N) for N training samples; 40000 test samples estimate
    the RMS to 0.35 % (one standard error), so 2 % is about 6 standard errors.
    """
    rng = np.random.default_rng(ports)
    device = wm.Interferometer.ideal(ports)
    train_hz = device.sweep_hz(2001)
    cal = wm.Calibrator(50e9).fit(device.powers(train_hz, POWER_W, NOISE_W, rng), train_hz)
    test_hz = random_test_frequencies(device, 40000, rng)
    predicted = cal.predict(device.powers(test_hz, POWER_W, NOISE_W, rng))
    rms = np.sqrt(np.mean(wm.frequency_error_hz(predicted, test_hz, device.true_fsr_hz) ** 2))
    bound = wm.crlb_ideal_frequency_std(ports, POWER_W, NOISE_W, 50e9) * np.sqrt(1 + 3 / 2001)
    assert rms == pytest.approx(bound, rel=0.02)


def test_bound_scales_with_power_and_noise():
    matrix = wm.Interferometer.table1(3, seed=4).true_map()
    base = wm.crlb_frequency_std(matrix, 0.3, POWER_W, NOISE_W, 50e9)
    assert wm.crlb_frequency_std(matrix, 0.3, 2 * POWER_W, NOISE_W, 50e9) == pytest.approx(base / 2)
    assert wm.crlb_frequency_std(matrix, 0.3, POWER_W, 3 * NOISE_W, 50e9) == pytest.approx(3 * base)
    per_sample = wm.crlb_frequency_std(matrix, [0.3, 0.3], [POWER_W, 2 * POWER_W], NOISE_W, 50e9)
    np.testing.assert_allclose(per_sample, [base, base / 2])


def test_bad_arguments():
    with pytest.raises(ValueError, match="map_ must have shape"):
        wm.crlb_frequency_std(np.ones((3, 2)), 0.0, 1e-3, 1e-7, 50e9)
    for noise in (0.0, [1e-7, 1e-7], [1e-7, -1e-7, 1e-7], [1e-7, np.nan, 1e-7]):
        with pytest.raises(InputError, match="noise_std") as info:
            wm.crlb_frequency_std(np.ones((3, 3)), 0.0, 1e-3, noise, 50e9)
        assert info.value.parameter == "noise_std"
    with pytest.raises(ValueError, match="ports must be >= 3"):
        wm.crlb_ideal_frequency_std(2, 1e-3, 1e-7, 50e9)
