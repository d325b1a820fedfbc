"""Re-anchoring to a reference laser, in process: the sanity check of a window (every bound
a probability), and the keeper on the simulated meter while its chip warms: the anchored
calibration stays true where the base drifts by GHz, a reading off by 50 standard
deviations and a shifted reference are refused every time, each attempt logged with the
offset before and after."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.exceptions import InputError
from wavemeter.service.reference import ReferenceKeeper
from wavemeter.service.reference_checks import check_window
from wavemeter.service.simulated import NOISE_W, POWER_W, simulated_meter

SIGMA_HZ = 14e6
REFERENCE_HZ = 193.414e12


def _window(rng, n=1000, offset=5e6, drift=2e7, seconds=1.0):
    times = np.linspace(0.0, seconds, n)
    error = offset + drift * times + rng.normal(0.0, SIGMA_HZ, n)
    return times, error, np.full(n, SIGMA_HZ), np.zeros(n, dtype=np.int64)


def _check(times, error, std, flags, **changes):
    settings = {
        "at_s": 1.05,
        "anchored_hz": 0.0,
        "allowance_hz": 1e8,
        "max_drift_hz_per_s": 2.6e8,
        **changes,
    }
    return check_window(times, error, std, flags, **settings)


def test_a_good_window_passes_and_its_line_is_extrapolated():
    check = _check(*_window(np.random.default_rng(1)))
    assert check.ok, check.reason
    assert check.fitted == 1000
    true_offset = 5e6 + 2e7 * 1.05
    assert abs(check.offset_hz - true_offset) < 5 * check.offset_std_hz
    assert abs(check.drift_hz_per_s - 2e7) < 5 * SIGMA_HZ / np.sqrt(1000 / 12)
    assert check.correction_hz == check.offset_hz
    assert 0.9 < check.scatter_ratio < 1.1


@pytest.mark.slow
def test_good_windows_are_almost_never_refused():
    """2000 windows of 30 readings: each check refuses a good one with p = 1e-6, so no
    refusal is expected (the chance of one is under 1 %)."""
    rng = np.random.default_rng(2)
    checks = [_check(*_window(rng, n=30, seconds=0.03)) for _ in range(2000)]
    assert [check.ok for check in checks].count(False) == 0
    assert all(check.fitted == 30 for check in checks)


@pytest.mark.parametrize(
    "spoil, reason",
    [
        (lambda w: w[1].__setitem__(500, w[1][500] + 50 * SIGMA_HZ), "standard deviations"),
        (lambda w: w[1].__setitem__(500, w[1][500] - 10 * SIGMA_HZ), "standard deviations"),
        (lambda w: w[3].__setitem__(10, int(wm.ReadingFlag.OFF_MODEL)), "flagged OFF_MODEL"),
        (lambda w: w[2].__setitem__(slice(None), SIGMA_HZ / 2), "scatter by"),
        (lambda w: w[2].__setitem__(slice(None), SIGMA_HZ * 2), "scatter by"),
        (lambda w: w[1].__iadd__(2e8), "off the anchor in force"),
        (lambda w: w[1].__iadd__(4e8 * w[0]), "drifts by"),
    ],
)
def test_a_spoilt_window_is_refused_with_its_reason(spoil, reason):
    window = _window(np.random.default_rng(3))
    spoil(window)
    check = _check(*window)
    assert not check.ok and reason in check.reason


def test_a_bend_in_the_drift_is_left_behind():
    """The drift stops half-way through the window: the line is fitted to the latest part
    (where the offset is flat), not across the bend."""
    times, error, std, flags = _window(np.random.default_rng(7), drift=0.0)
    error += 3e8 * np.minimum(times, 0.5)  # 300 MHz/s until 0.5 s, then still
    check = _check(times, error, std, flags, allowance_hz=3e8)
    assert check.ok, check.reason
    assert check.fitted <= 500
    assert abs(check.offset_hz - (5e6 + 1.5e8)) < 5 * check.offset_std_hz
    straight = _check(times[:1], error[:1], std[:1], flags[:1])
    assert not straight.ok and "fewer than" in straight.reason


@pytest.fixture(scope="module")
def meter():
    device, calibration = simulated_meter(7)
    return device.with_thermal("sin"), calibration  # silicon nitride: 2.6 GHz/K


def _feed(keeper, device, seconds, *, rng, ramp_k_per_s=0.1, spoil=None, rate=1000.0, chunk=20):
    """Feed the keeper ``seconds`` of reference readings, the chip warming; the events,
    and the calibration in force before each chunk."""
    n = int(seconds * rate)
    times = np.arange(n) / rate
    truth = np.full(n, REFERENCE_HZ)
    if spoil is not None:
        spoil(truth, times)
    temperature = device.reference_temperature_k + ramp_k_per_s * times
    powers = device.powers(
        truth, power_w=POWER_W, noise_w=NOISE_W, rng=rng, temperature_k=temperature
    )
    events, in_force = [], []
    for start in range(0, n, chunk):
        part = slice(start, start + chunk)
        reading = keeper.calibration.readout(powers[part])
        in_force.append(keeper.calibration)
        event = keeper.add(times[part], powers[part], reading.frequency_hz, reading.flags)
        if event is not None:
            events.append(event)
    return events, in_force, temperature[-1]


def _error_at(calibration, device, frequency_hz, temperature_k, rng) -> float:
    powers = device.powers(
        np.full(2000, frequency_hz),
        power_w=POWER_W,
        noise_w=NOISE_W,
        rng=rng,
        temperature_k=temperature_k,
    )
    return float(np.mean(calibration.predict(powers)) - frequency_hz)


def test_the_keeper_keeps_the_meter_true_while_the_chip_warms(meter):
    """0.1 K/s for 8 s moves the fringes by 2 GHz: the base calibration reads a laser
    elsewhere in the span 2 GHz off; the anchored one within a few MHz (the offset's
    standard error, and the calibration's own change of error across the span)."""
    device, calibration = meter
    keeper = ReferenceKeeper(calibration, REFERENCE_HZ, interval_s=0.2, window_s=1.0)
    rng = np.random.default_rng(4)
    events, in_force, _ = _feed(keeper, device, 8.0, rng=rng)
    assert len(events) == 39 and keeper.refused == 0 and keeper.alarm is None
    assert all(abs(event.after_hz) < event.offset_std_hz for event in events)
    # the window handed to reanchor in bins along the fitted drift (0.26 GHz/s: about 35 of
    # ~29 ms), each of which the calibration's own scatter test finds one line
    records = {id(c): c.diagnostics_["reanchor"] for c in in_force if c is not calibration}
    assert len(records) == 39
    assert all(r["reference_check"]["verdict"] == "ok" for r in records.values())
    assert min(len(r["lines_hz"]) for r in records.values()) > 1
    assert all(0 < event.before_hz < 4 * (0.26e9 * 0.2) for event in events[5:])
    # the last anchor is for the middle of the interval after it
    temperature = device.reference_temperature_k + 0.1 * (events[-1].time_s + 0.1)
    base = _error_at(calibration, device, 193.395e12, temperature, rng)
    anchored = _error_at(keeper.calibration, device, 193.395e12, temperature, rng)
    assert base > 2.0e9
    assert abs(anchored) < 5e6


def test_a_reading_off_by_fifty_sigma_is_refused_while_it_is_in_the_window(meter):
    device, calibration = meter
    keeper = ReferenceKeeper(calibration, REFERENCE_HZ, interval_s=0.2, window_s=1.0)

    def spoil(truth, times):
        truth[3000] += 50 * SIGMA_HZ

    events, in_force, _ = _feed(keeper, device, 6.0, rng=np.random.default_rng(5), spoil=spoil)
    holding = [e for e in events if 3.0 <= e.time_s < 4.0 - 1e-9]
    assert len(holding) == 5 and all(not e.accepted for e in holding)
    assert all("standard deviations" in e.reason for e in holding)
    assert all(e.accepted for e in events if not 3.0 <= e.time_s < 4.0 - 1e-9)
    assert keeper.refused == 5 and keeper.alarm is None  # accepted again since
    # while refused, the calibration in force did not change
    chunks = [k for k in range(len(in_force)) if 3.1 <= (k + 1) * 0.02 < 4.0]
    assert len({id(in_force[k]) for k in chunks}) == 1


def test_a_reference_shifted_by_fifty_sigma_is_refused_every_time(meter):
    device, calibration = meter
    keeper = ReferenceKeeper(calibration, REFERENCE_HZ, interval_s=0.2, window_s=1.0)

    def spoil(truth, times):
        truth[times >= 3.0] += 50 * SIGMA_HZ  # the reference laser jumped

    events, _, _ = _feed(keeper, device, 5.0, rng=np.random.default_rng(6), spoil=spoil)
    after = [e for e in events if e.time_s >= 3.0]
    assert len(after) == 10 and not any(e.accepted for e in after)
    assert keeper.alarm is not None and keeper.refused == 10
    assert all(e.accepted for e in events if e.time_s < 3.0)


def test_a_calibration_that_cannot_be_re_anchored_or_a_reference_outside_it_is_refused(meter):
    device, calibration = meter
    sweep = device.sweep_hz(400)
    conventional = wm.ConventionalCalibrator(fsr_hz=50e9).fit(
        device.powers(sweep, power_w=POWER_W, noise_w=NOISE_W, rng=1), sweep
    )
    with pytest.raises(InputError, match="cannot be re-anchored"):
        ReferenceKeeper(conventional, REFERENCE_HZ)
    with pytest.raises(InputError, match="inside the calibration's span"):
        ReferenceKeeper(calibration, 194.0e12)
    with pytest.raises(InputError, match="interval_s"):
        ReferenceKeeper(calibration, REFERENCE_HZ, interval_s=0.0)
