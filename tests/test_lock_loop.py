"""The lock's loop, in process: gains from a bandwidth, the loop's noise against its
closed form, bad readings that never move the output, the capture range, railing and
anti-windup, holds, bumpless engaging, scans, bad settings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wavemeter import ReadingFlag
from wavemeter.exceptions import InputError
from wavemeter.service.lock_loop import (
    CAPTURE,
    HOLDING,
    LOCKED,
    NO_SIGNAL,
    RAILING,
    UNLOCKED,
    LockLoop,
    LockSettings,
)
from wavemeter.service.setpoints import Scan

SETPOINT_HZ = 193.4e12
TUNING_HZ_PER_V = 5e8
RATE_HZ = 1000.0


def _settings(**changes) -> LockSettings:
    values = {
        "actuator_hz_per_v": TUNING_HZ_PER_V,
        "bandwidth_hz": 2.0,
        "response_s": 0.0,
        **changes,
    }
    setpoint = values.pop("setpoint", SETPOINT_HZ)
    return LockSettings.from_bandwidth(setpoint, **values)


def _locked(settings=None, output_v=0.0) -> LockLoop:
    loop = LockLoop(settings or _settings(), output_v, interval_s=1 / RATE_HZ)
    loop.engage()
    return loop


class _Laser:
    """An ideal actuator on a laser at ``free_hz``: the frequency follows the output."""

    def __init__(self, free_hz: float):
        self.free_hz = free_hz
        self.voltage_v = 0.0

    @property
    def frequency_hz(self) -> float:
        return self.free_hz + TUNING_HZ_PER_V * self.voltage_v


def _run(loop, laser, readings, start=0, noise=None):
    truth = np.empty(readings)
    for k in range(readings):
        truth[k] = laser.frequency_hz
        reading = truth[k] + (0.0 if noise is None else noise[k])
        laser.voltage_v = loop.step((start + k) / RATE_HZ, reading, 0)
    return truth


def test_gains_from_a_bandwidth_cancel_the_actuator_pole():
    settings = _settings(bandwidth_hz=3.0, response_s=2e-3)
    ki = 2 * math.pi * 3.0 / TUNING_HZ_PER_V
    assert settings.ki_v_per_hz_s == pytest.approx(ki, rel=1e-12)
    assert settings.kp_v_per_hz == pytest.approx(ki * 2e-3, rel=1e-12)
    assert settings.bandwidth_hz == 3.0


def test_the_loop_closes_at_its_bandwidth():
    """An ideal actuator and a noiseless meter: the error decays as exp(-2 pi B t), the
    discrete loop's (1 - 2 pi B T)^k."""
    bandwidth = 2.0
    loop = _locked(_settings(bandwidth_hz=bandwidth))
    laser = _Laser(SETPOINT_HZ + 1e8)
    truth = _run(loop, laser, 400)
    gain = 2 * math.pi * bandwidth / RATE_HZ
    expected = 1e8 * (1 - gain) ** np.arange(400)
    np.testing.assert_allclose(truth - SETPOINT_HZ, expected, rtol=1e-9, atol=0.1)
    assert loop.state == LOCKED and loop.updates == 400


def test_locked_on_a_noisy_meter_the_laser_scatters_as_the_closed_form():
    """Pure integral gain g per reading on white meter noise sigma: the laser's error is an
    AR(1) process of variance g sigma^2 / (2 - g). Over N readings the variance estimate
    has a relative spread ~ 1 / sqrt(N g); the tolerance is four of them."""
    sigma, bandwidth, readings = 14e6, 1.0, 60_000
    gain = 2 * math.pi * bandwidth / RATE_HZ
    noise = np.random.default_rng(5).normal(0.0, sigma, readings)
    loop = _locked(_settings(bandwidth_hz=bandwidth))
    truth = _run(loop, _Laser(SETPOINT_HZ), readings, noise=noise)
    variance = np.mean((truth[2000:] - SETPOINT_HZ) ** 2)
    expected = gain * sigma**2 / (2 - gain)
    spread = 1 / math.sqrt((readings - 2000) * gain)
    assert abs(variance / expected - 1) < 4 * spread


@pytest.mark.parametrize(
    "flag",
    [
        ReadingFlag.INVALID,
        ReadingFlag.OFF_MODEL,
        ReadingFlag.OUTSIDE_SPAN,
        ReadingFlag.ORDER_AMBIGUOUS,
        ReadingFlag.OFF_MODEL | ReadingFlag.POWER_RANGE,
    ],
)
def test_a_flagged_reading_never_moves_the_output(flag):
    loop = _locked()
    laser = _Laser(SETPOINT_HZ + 3e7)
    _run(loop, laser, 50)
    rng = np.random.default_rng(2)
    for k in range(200):
        before = loop.output_v
        wild = SETPOINT_HZ + rng.uniform(-2e9, 2e9)  # a bad reading says anything
        assert loop.step((50 + k) / RATE_HZ, wild, int(flag)) == before
        assert loop.state == HOLDING and math.isnan(loop.reading_error_hz)
    assert loop.held == 200 and loop.updates == 50
    loop.step(250 / RATE_HZ, laser.frequency_hz, 0)
    assert loop.state == LOCKED and loop.updates == 51


def test_a_nan_reading_never_moves_the_output():
    loop = _locked()
    _run(loop, _Laser(SETPOINT_HZ + 3e7), 20)
    before = loop.output_v
    assert loop.step(0.03, float("nan"), 0) == before
    assert loop.held == 1


def test_a_flag_that_says_nothing_bad_does_not_hold():
    loop = _locked()
    loop.step(0.0, SETPOINT_HZ + 1e6, int(ReadingFlag.TEMPERATURE_RANGE))
    assert loop.updates == 1 and loop.held == 0


def test_an_error_beyond_the_capture_range_unlocks_and_alarms_and_keeps_the_output():
    loop = _locked(_settings(capture_range_hz=3e9))
    laser = _Laser(SETPOINT_HZ + 5e8)
    _run(loop, laser, 300)
    held_at = loop.output_v
    loop.step(0.301, SETPOINT_HZ + 3.2e9, 0)  # a mode hop
    assert loop.state == UNLOCKED and loop.output_v == held_at
    assert CAPTURE in loop.alarms and loop.alarm_counts[CAPTURE] == 1
    assert "capture range" in loop.alarms[CAPTURE]
    for k in range(100):  # unlocked: readings do nothing
        assert loop.step(0.302 + k / RATE_HZ, SETPOINT_HZ - 1e7, 0) == held_at
    loop.engage()
    assert loop.state == LOCKED and CAPTURE not in loop.alarms
    assert loop.alarm_counts[CAPTURE] == 1


def test_a_setpoint_jump_beyond_the_capture_range_unlocks():
    loop = _locked(_settings(capture_range_hz=1e9))
    laser = _Laser(SETPOINT_HZ)
    _run(loop, laser, 100)
    loop.engage(loop.settings.with_setpoint(SETPOINT_HZ + 1.5e9))
    laser.voltage_v = loop.step(0.1, laser.frequency_hz, 0)
    assert loop.state == UNLOCKED and CAPTURE in loop.alarms


def test_an_output_at_its_limit_alarms_after_the_rail_time_and_does_not_wind_up():
    settings = _settings(output_limits_v=(-1.0, 1.0), rail_s=0.5, bandwidth_hz=5.0)
    loop = _locked(settings)
    laser = _Laser(SETPOINT_HZ - 8e8)  # needs 1.6 V: beyond the limit
    _run(loop, laser, 400)
    assert loop.output_v == 1.0 and RAILING not in loop.alarms  # railing for < 0.5 s
    _run(loop, laser, 3000, start=400)
    assert RAILING in loop.alarms and loop.alarm_counts[RAILING] == 1
    # the laser comes back within reach: with no wind-up the output leaves the limit at the
    # first update, not after unwinding three seconds of integrated error
    laser.free_hz = SETPOINT_HZ - 2e8
    laser.voltage_v = loop.step(3.4, laser.frequency_hz, 0)
    assert loop.output_v < 1.0 and RAILING not in loop.alarms
    truth = _run(loop, laser, 500, start=3401)
    assert abs(truth[-1] - SETPOINT_HZ) < 1e3
    assert loop.alarm_counts[RAILING] == 1


def test_every_railing_alarms_when_setpoints_out_of_reach_alternate_with_ones_in_reach():
    """Re-engaging clears the rail timer; the alarm must clear with it, or the next railing
    (the same alarm still raised) would go uncounted."""
    settings = _settings(output_limits_v=(-1.0, 1.0), rail_s=0.5, bandwidth_hz=5.0)
    loop = _locked(settings)
    laser = _Laser(SETPOINT_HZ)
    start = 0
    for _ in range(3):
        loop.engage(settings.with_setpoint(SETPOINT_HZ + 8e8))  # needs 1.6 V
        _run(loop, laser, 2000, start=start)
        assert loop.output_v == 1.0 and RAILING in loop.alarms
        loop.engage(settings)
        _run(loop, laser, 1000, start=start + 2000)
        assert RAILING not in loop.alarms
        start += 3000
    assert loop.alarm_counts[RAILING] == 3


def test_a_hold_freezes_the_output_until_released():
    loop = _locked()
    laser = _Laser(SETPOINT_HZ + 2e8)
    _run(loop, laser, 30)
    frozen = loop.output_v
    loop.hold(NO_SIGNAL, "no reading for 1 s")
    assert loop.state == HOLDING and NO_SIGNAL in loop.alarms
    for k in range(100):
        assert loop.step(0.03 + k / RATE_HZ, laser.frequency_hz, 0) == frozen
    assert loop.held == 100
    loop.release(NO_SIGNAL)
    assert loop.state == LOCKED and NO_SIGNAL not in loop.alarms
    loop.step(0.2, laser.frequency_hz, 0)
    assert loop.output_v != frozen


def test_a_pause_in_the_readings_does_not_kick_the_output():
    """The integrator steps by the reading interval, not by the time since the last
    reading: after a 10 s pause the next update is an ordinary one."""
    loop = _locked()
    laser = _Laser(SETPOINT_HZ + 2e8)
    _run(loop, laser, 30)
    before, error = loop.output_v, laser.frequency_hz - SETPOINT_HZ
    loop.step(10.0, laser.frequency_hz, 0)
    expected = loop.settings.ki_v_per_hz_s * error / RATE_HZ
    assert before - loop.output_v == pytest.approx(expected, rel=0.05)


def test_engaging_is_bumpless_and_a_new_setpoint_keeps_the_integrator():
    loop = LockLoop(_settings(response_s=1e-3), 2.5, interval_s=1 / RATE_HZ)
    loop.engage()
    assert loop.output_v == 2.5
    error = 1e7
    loop.step(0.0, SETPOINT_HZ + error, 0)
    settings = loop.settings
    step = settings.kp_v_per_hz * error + settings.ki_v_per_hz_s * error / RATE_HZ
    assert loop.output_v == pytest.approx(2.5 - step, rel=1e-12)
    held = loop.output_v
    loop.engage(settings.with_setpoint(SETPOINT_HZ + 1e6))
    assert loop.output_v == held and loop.state == LOCKED


def test_a_triangle_scan_is_followed():
    scan = Scan(SETPOINT_HZ, amplitude_hz=2e8, period_s=4.0, shape="triangle")
    loop = _locked(_settings(setpoint=scan, bandwidth_hz=10.0))
    laser = _Laser(SETPOINT_HZ)
    truth = _run(loop, laser, 8000)
    times = np.arange(8000) / RATE_HZ
    target = np.array([scan.at(t) for t in times])
    # a type-1 loop follows a ramp of slope r with the lag r / (2 pi B)
    slope = 4 * 2e8 / 4.0
    lag = slope / (2 * math.pi * 10.0)
    settled = times > 0.5
    corners = np.abs(((times + 1.0) % 2.0) - 1.0) > 0.95  # a turn of the triangle: skipped
    error = np.abs(truth - target)[settled & ~corners]
    assert np.max(error) < 1.05 * lag + 1e3
    assert np.max(error) > 0.9 * lag


def test_a_bandwidth_too_high_for_the_readings_is_refused():
    settings = _settings(bandwidth_hz=100.0)
    with pytest.raises(InputError, match="bandwidth below") as caught:
        settings.check_interval(1 / RATE_HZ, TUNING_HZ_PER_V)
    assert caught.value.parameter == "bandwidth_hz"
    _settings(bandwidth_hz=50.0).check_interval(1 / RATE_HZ, TUNING_HZ_PER_V)


@pytest.mark.parametrize(
    "changes, parameter",
    [
        ({"setpoint": -1.0}, "setpoint_hz"),
        ({"setpoint": float("inf")}, "setpoint_hz"),
        ({"bandwidth_hz": 0.0}, "bandwidth_hz"),
        ({"actuator_hz_per_v": 0.0}, "actuator_hz_per_v"),
        ({"output_limits_v": (1.0, -1.0)}, "output_limits_v"),
        ({"capture_range_hz": 0.0}, "capture_range_hz"),
        ({"average": 0}, "average"),
        ({"rail_s": -1.0}, "rail_s"),
    ],
)
def test_bad_settings_are_refused_naming_them(changes, parameter):
    with pytest.raises(InputError) as caught:
        _settings(**changes)
    assert caught.value.parameter == parameter


def test_a_lock_without_gain_is_refused():
    with pytest.raises(InputError, match="needs a gain"):
        LockSettings(SETPOINT_HZ, kp_v_per_hz=0.0, ki_v_per_hz_s=0.0)


@pytest.mark.parametrize(
    "changes, parameter",
    [
        ({"amplitude_hz": -1.0}, "amplitude_hz"),
        ({"period_s": 0.0}, "period_s"),
        ({"shape": "sine"}, "shape"),
        ({"center_hz": 0.0}, "center_hz"),
    ],
)
def test_bad_scans_are_refused_naming_them(changes, parameter):
    values = {"center_hz": SETPOINT_HZ, "amplitude_hz": 1e8, "period_s": 1.0, **changes}
    with pytest.raises(InputError) as caught:
        Scan(**values)
    assert caught.value.parameter == parameter
