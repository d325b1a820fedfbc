"""The simulated interferometer: fields versus the exact map, Table 1 draws, readings."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.model.couplers import mmi_matrix
from wavemeter.simulation.coupler_draws import symmetry_classes

from .helpers import NOISE_W, POWER_W


def _objects(device, frequency_hz, power_w=POWER_W):
    phase = wm.model.cone.delay_phase_rad(frequency_hz, device.center_hz, device.delay_s)
    return wm.cone_vectors(phase, power_w)


@pytest.mark.parametrize("ports", [3, 4, 5, 8])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_true_map_reproduces_field_simulation(ports, seed):
    device = wm.Interferometer.table1(ports, seed=seed)
    f = device.sweep_hz(257, span_fsr=3.0)
    readings = device.powers(f, POWER_W)
    np.testing.assert_allclose(readings, _objects(device, f) @ device.true_map().T, atol=1e-18)


@pytest.mark.parametrize("ports", [3, 4, 5, 8])
def test_ideal_device_is_orthonormal_up_to_scale(ports):
    device = wm.Interferometer.ideal(ports)
    scaled = device.true_map() * np.sqrt(2 * ports)  # A = O / sqrt(2 n) (Eq. 16, 27)
    np.testing.assert_allclose(scaled.T @ scaled, np.eye(3), atol=1e-12)
    assert device.true_fsr_hz == pytest.approx(50e9, rel=1e-15)
    # a lossless ideal device conserves power: the ports add up to the source power
    readings = device.powers(device.sweep_hz(100), POWER_W)
    np.testing.assert_allclose(readings.sum(axis=1), POWER_W, rtol=1e-12)


def test_ideal_3x3_matches_eq27():
    """Eq. 27: p_j = K/3 [1 + cos(t - phi_j)], phi = (-5, 3, -1) pi/6, up to origin/direction."""
    matrix = wm.Interferometer.ideal(3).true_map()
    amplitude = np.hypot(matrix[:, 0], matrix[:, 1])
    np.testing.assert_allclose(amplitude, 1 / 3, atol=1e-15)
    np.testing.assert_allclose(matrix[:, 2] * np.sqrt(2), 1 / 3, atol=1e-15)
    phases = np.arctan2(matrix[:, 1], matrix[:, 0])  # fringe cos(t - phi_j)
    eq27 = np.array([-5, 3, -1]) * np.pi / 6
    relative = wm.wrap_phase_rad(phases - phases[0])
    expected = wm.wrap_phase_rad(eq27 - eq27[0])
    assert min(np.abs(relative - s * expected).max() for s in (1, -1)) < 1e-12


def test_symmetry_classes_group_equal_entries():
    for n in (3, 4, 5, 8):
        matrix, labels = mmi_matrix(n), symmetry_classes(n)
        for label in np.unique(labels):
            values = matrix[labels == label]
            np.testing.assert_allclose(values, values[0], atol=1e-12)


@pytest.mark.slow
def test_table1_draws_are_seeded_and_realistic():
    a = wm.Interferometer.table1(3, seed=5)
    b = wm.Interferometer.table1(3, seed=5)
    c = wm.Interferometer.table1(3, seed=6)
    np.testing.assert_array_equal(a.true_map(), b.true_map())
    assert not np.array_equal(a.true_map(), c.true_map())
    delays = np.array([wm.Interferometer.table1(3, seed=s).delay_s for s in range(400)])
    responsivity = np.array([wm.Interferometer.table1(3, seed=s).responsivity for s in range(400)])
    biases = np.array([wm.Interferometer.table1(3, seed=s).bias_phase_rad for s in range(400)])
    # 400 draws: the sample std is within ~4 standard errors (3.5 %) of the Table 1 sigma
    assert np.std(delays * 50e9) == pytest.approx(0.05, rel=0.15)
    assert np.std(responsivity) == pytest.approx(0.10, rel=0.15)
    assert biases.min() > -np.pi and biases.max() <= np.pi
    assert np.std(biases) == pytest.approx(2 * np.pi / np.sqrt(12), rel=0.15)


def test_table1_without_impairments_is_ideal():
    device = wm.Interferometer.table1(
        4, seed=3, symmetric_sigma=0, breaking_sigma=0, delay_sigma=0, responsivity_sigma=0
    )
    ideal = dataclasses.replace(wm.Interferometer.ideal(4), bias_phase_rad=device.bias_phase_rad)
    np.testing.assert_allclose(device.true_map(), ideal.true_map(), atol=1e-15)


def test_noise_and_per_sample_power(rng):
    device = wm.Interferometer.table1(3, seed=1)
    f = np.full(20000, device.center_hz)
    noisy = device.powers(f, POWER_W, NOISE_W, rng)
    clean = device.powers(f, POWER_W)
    # 20000 x 3 draws: the std is within 2 % (about 6 standard errors)
    assert np.std(noisy - clean) == pytest.approx(NOISE_W, rel=0.02)
    power = np.linspace(0.5e-3, 1.5e-3, f.size)
    np.testing.assert_allclose(
        device.powers(f, power), clean * (power / POWER_W)[:, None], rtol=1e-14
    )
    np.testing.assert_allclose(device.monitor(power), device.monitor_ratio * power)


def test_temperature_moves_the_bias_linearly():
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=2), thermal_phase_rad_per_k=0.25)
    f = device.sweep_hz(64)
    hot = device.powers(f, POWER_W, temperature_k=device.reference_temperature_k + 2.0)
    shifted = device.powers(f + 0.5 / (2 * np.pi * device.delay_s), POWER_W)
    np.testing.assert_allclose(hot, shifted, atol=1e-17)
    np.testing.assert_allclose(
        device.true_map(device.reference_temperature_k + 2.0),
        device.true_map() @ _rotation(0.5),
        atol=1e-17,
    )


def _rotation(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_powers_rejects_bad_input():
    device = wm.Interferometer.ideal(3)
    with pytest.raises(ValueError, match="power_w"):
        device.powers([1.9e14], power_w=-1.0)
    with pytest.raises(ValueError, match="noise_w"):
        device.powers([1.9e14], noise_w=-1.0)
    with pytest.raises(wm.InputError, match="rng"):
        device.powers([1.9e14], noise_w=1e-7, rng="seed")
    with pytest.raises(ValueError, match="inputs"):
        wm.Interferometer(mmi_matrix(3), np.ones(2), inputs=(0, 0))
