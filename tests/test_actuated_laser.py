"""The actuated laser: the actuator's first-order response as interval means, clipping,
additivity with the free-running noise, mode hops, continuity across blocks, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from wavemeter.exceptions import InputError
from wavemeter.simulation import LASER_PRESETS, ActuatedLaser, LaserNoise

CENTER_HZ = 193.4e12
RATE_HZ = 1000.0
QUIET = LaserNoise()


def test_the_actuator_responds_to_a_step_as_the_interval_means_of_a_first_order_response():
    tuning, response = 4e8, 2e-3
    laser = ActuatedLaser(
        CENTER_HZ, RATE_HZ, noise=QUIET, tuning_hz_per_v=tuning, response_s=response
    )
    laser.set_voltage(1.5)
    # taken in pieces of 1, 3 and 16 readings: the response carries over
    frequency = np.concatenate([laser.take(1), laser.take(3), laser.take(16)])
    k = np.arange(20)
    step = 1 / RATE_HZ
    # mean of 1 - exp(-t / response) over [k, k + 1] step
    mean = 1 - response / step * (np.exp(-k * step / response) - np.exp(-(k + 1) * step / response))
    # to float64 at 193 THz (a step of 0.03 Hz)
    np.testing.assert_allclose(frequency - CENTER_HZ, tuning * 1.5 * mean, rtol=0, atol=0.1)
    assert laser.actuator_v == pytest.approx(1.5 * (1 - np.exp(-20 * step / response)), rel=1e-12)


def test_without_a_response_time_the_laser_follows_at_once_and_the_range_clips():
    laser = ActuatedLaser(CENTER_HZ, RATE_HZ, noise=QUIET, tuning_hz_per_v=-2e8, response_s=0)
    assert laser.set_voltage(25.0) == 10.0  # the default range is -10 .. 10 V
    np.testing.assert_allclose(laser.take(5) - CENTER_HZ, -2e8 * 10.0, atol=0.1)
    assert laser.set_voltage(-3.0) == -3.0
    np.testing.assert_allclose(laser.take(2) - CENTER_HZ, 6e8, atol=0.1)


def test_the_actuator_adds_to_the_same_free_running_frequency():
    """Two lasers of one seed, one held at 2 V: they differ by the tuning alone."""
    free = ActuatedLaser(CENTER_HZ, RATE_HZ, noise="ecdl", response_s=0, rng=4)
    driven = ActuatedLaser(CENTER_HZ, RATE_HZ, noise="ecdl", response_s=0, rng=4)
    driven.set_voltage(2.0)
    a = np.concatenate([free.take(n) for n in (7, 1, 500, 30_000)])
    b = np.concatenate([driven.take(n) for n in (30_000, 500, 8)])
    np.testing.assert_allclose(b - a, 2.0 * 5e8, atol=0.1)
    assert np.std(np.diff(a)) > 1e3  # the free-running part is noisy


def test_mode_hops_are_jumps_of_the_hop_size_at_the_poisson_rate():
    rate_per_s, seconds = 2.0, 100.0
    laser = ActuatedLaser(
        CENTER_HZ,
        RATE_HZ,
        noise=QUIET,
        mode_hop_hz=3e9,
        mode_hop_rate_per_s=rate_per_s,
        block_s=7.0,
        rng=11,
    )
    frequency = np.concatenate([laser.take(1000) for _ in range(int(seconds))])
    jumps = np.diff(frequency)
    hops = np.abs(jumps) > 1e9
    # two hops in one reading interval add to 0 or +-6 GHz: count hops by size
    sizes = np.round(np.abs(jumps[hops]) / 3e9)
    assert set(np.unique(sizes)) <= {1.0, 2.0}
    assert np.all(np.abs(jumps[~hops]) < 1.0)
    expected = rate_per_s * seconds
    # Poisson: within 5 standard deviations (a false failure about once in 3 million)
    assert abs(laser.hops - expected) < 5 * np.sqrt(expected)
    assert laser.hops >= int(sizes.sum())  # two opposite hops in one interval cancel


def test_the_random_walk_carries_over_block_boundaries():
    noise = LaserNoise(random_walk_fm_hz2_per_s=1e12)
    laser = ActuatedLaser(CENTER_HZ, RATE_HZ, noise=noise, block_s=1.0, rng=3)
    frequency = laser.take(10_000)
    step_std = np.sqrt(2 * np.pi**2 * 1e12 / RATE_HZ)  # the walk's step per reading
    jumps = np.abs(np.diff(frequency))
    boundaries = jumps[999::1000]  # between the last reading of a block and the next
    assert np.all(boundaries < 6 * step_std)
    assert np.std(jumps) < 1.5 * step_std


def test_the_presets_are_laser_noise():
    assert set(LASER_PRESETS) == {"ecdl", "reference"}
    ecdl = LASER_PRESETS["ecdl"]
    # a 94 kHz Lorentzian linewidth, 1 MHz Allan deviation at 1 s from the walk
    assert np.pi * ecdl.white_fm_hz2_per_hz == pytest.approx(94e3, rel=0.01)
    walk_adev = np.sqrt(2 * np.pi**2 * ecdl.random_walk_fm_hz2_per_s / 3)
    assert walk_adev == pytest.approx(1e6, rel=0.01)
    assert LASER_PRESETS["reference"].drift_hz_per_s == 0


@pytest.mark.parametrize(
    "kwargs, parameter",
    [
        ({"tuning_hz_per_v": 0.0}, "tuning_hz_per_v"),
        ({"voltage_range_v": (5.0, -5.0)}, "voltage_range_v"),
        ({"noise": "dye"}, "noise"),
        ({"mode_hop_rate_per_s": -1.0}, "mode_hop_rate_per_s"),
        ({"response_s": -1e-3}, "response_s"),
        ({"rate_hz": 0.0}, "rate_hz"),
    ],
)
def test_bad_settings_are_refused_naming_them(kwargs, parameter):
    settings = {"center_hz": CENTER_HZ, "rate_hz": RATE_HZ, **kwargs}
    with pytest.raises(InputError) as caught:
        ActuatedLaser(settings.pop("center_hz"), settings.pop("rate_hz"), **settings)
    assert caught.value.parameter == parameter


def test_a_voltage_that_is_not_finite_is_refused():
    laser = ActuatedLaser(CENTER_HZ, RATE_HZ, noise=QUIET)
    with pytest.raises(InputError, match="not finite"):
        laser.set_voltage(float("nan"))
    assert laser.voltage_v == 0.0
