"""Flags only some calibrations raise never move a lock's output, through a live service.

The simulated meter of ``serve --simulate`` reads one FSR: it never flags ``ORDER_AMBIGUOUS``
or ``OUTSIDE_SPAN``. Here a service in this process (real sockets on 127.0.0.1) reads a
cascade meter (1 THz / 100 GHz / 10 GHz stages over 0.8 THz, as ``tests/test_cascade.py``),
which flags many readings at 30 times the detector noise ``ORDER_AMBIGUOUS`` (the batch's
noise makes the finest stage's order a guess) and readings of a laser beyond the band
``OUTSIDE_SPAN``. Fed through ``Server.feed`` between clean readings, not one flagged reading
moves the output, each is counted as held, and the clean readings after them move it again.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ._service import wait_for
from .helpers import NOISE_W, POWER_W, RecordingSink

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

import wavemeter as wm  # noqa: E402
from wavemeter.service import Client, Server, read_log  # noqa: E402
from wavemeter.service.lock_loop import HOLD_FLAGS  # noqa: E402

pytestmark = pytest.mark.slow

FSRS_HZ = (1e12, 100e9, 10e9)
BAND_HZ = 0.8e12
LOCAL = "tcp://127.0.0.1:0"
RATE_HZ = 1000.0


@pytest.fixture(scope="module")
def cascade():
    device = wm.CascadeInterferometer.table1(FSRS_HZ, ports=3, seed=4)
    low = device.center_hz - BAND_HZ / 2
    sweep_hz = low + BAND_HZ * np.arange(6000) / 5999
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=11)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        calibration = wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(sweep, sweep_hz)
    return device, calibration


def test_order_ambiguous_and_outside_span_readings_never_move_the_output(cascade, tmp_path):
    device, calibration = cascade
    sink = RecordingSink()
    setpoint = device.center_hz + 1e9
    rng = np.random.default_rng(5)
    taken = 0

    def feed(server, frequency_hz, readings, noise_w=NOISE_W):
        nonlocal taken
        powers = device.powers(np.full(readings, frequency_hz), POWER_W, noise_w, rng=rng)
        times = 1000.0 + (taken + np.arange(readings)) / RATE_HZ
        taken += readings
        server.feed(powers, time_s=times, channel=0)

    server = Server(
        calibration,
        publish=LOCAL,
        control=LOCAL,
        http=None,
        log=tmp_path,
        log_options={"flush_s": 0.05},
        outputs={0: (sink, "recording sink")},
        signal_timeout_s=60.0,
    )
    with server, Client(server.addresses["publish"], server.addresses["control"]) as client:
        # capture range 1 THz: the readings beyond the band are held by their flag, not by it
        client.lock(0, setpoint, actuator_hz_per_v=5e8, bandwidth_hz=2.0, capture_range_hz=1e12)
        feed(server, setpoint - 2e7, 100)
        assert wait_for(lambda: client.lock_status(0)["updates"] == 100, 20)
        feed(server, setpoint - 2e7, 200, noise_w=30 * NOISE_W)
        feed(server, calibration.span_hz_[1] + 50e9, 50)
        feed(server, setpoint - 2e7, 50)

        def seen():
            status = client.lock_status(0)
            return status["updates"] + status["held_readings"] == 400

        assert wait_for(seen, 20)
        status = client.lock_status(0)
    assert status["state"] == "locked" and status["alarms"] == {}
    table = read_log(tmp_path, channel=0)
    flags = table["flags"].to_numpy()
    outputs = table["lock_output_v"].to_numpy()
    assert len(flags) == 400
    noisy, beyond = flags[100:300], flags[300:350]
    # at 30 times the noise the finest stage's order is a guess for many readings (how many
    # depends on the blocks the service reads them in, whose noise the cascade estimates:
    # 61 to 193 of the 200 seen); the others are honest readings with 145 MHz of noise
    assert np.count_nonzero(noisy & wm.ReadingFlag.ORDER_AMBIGUOUS) >= 20
    assert np.all(beyond & wm.ReadingFlag.OUTSIDE_SPAN)
    assert not np.any(flags[:100]) and not np.any(flags[350:])
    held = np.flatnonzero(flags & HOLD_FLAGS)
    assert status["held_readings"] == len(held) and status["updates"] == 400 - len(held)
    assert np.all(outputs[held] == outputs[held - 1])  # not one moved the output
    assert len(sink.written) > 0 and sink.written[-1] == outputs[-1]
    assert np.all(np.diff(outputs[350:]) > 0)  # 20 MHz low: the clean readings move it
