"""Locks in a service run in this process (a Server in a thread, real sockets on
127.0.0.1, readings handed in with ``Server.feed``, a sink that records what it is told):
requests checked before they change anything, ownership and taking over, the lock's fields
on the data stream, flagged readings held, no signal and a silent owner holding (not
zeroing) the output, a failing output alarmed."""

from __future__ import annotations

import time

import numpy as np
import pytest

from ._service import wait_for
from .helpers import RecordingSink

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

from wavemeter.service import Client, Server, ServiceError, read_log  # noqa: E402
from wavemeter.service.setpoints import Scan  # noqa: E402
from wavemeter.service.simulated import NOISE_W, POWER_W, simulated_meter  # noqa: E402

LOCAL = "tcp://127.0.0.1:0"
RATE_HZ = 1000.0


@pytest.fixture(scope="module")
def meter():
    return simulated_meter(7)


@pytest.fixture
def served(meter, tmp_path):
    """A server with outputs on channels 0 and 1 (none on 2), logging into ``tmp_path``;
    stopped on the way out."""
    device, calibration = meter
    sinks = {0: RecordingSink(), 1: RecordingSink()}
    server = Server(
        calibration,
        publish=LOCAL,
        control=LOCAL,
        http=None,
        log=tmp_path,
        log_options={"flush_s": 0.05},
        signal_timeout_s=0.3,
        outputs={channel: (sink, f"recording sink {channel}") for channel, sink in sinks.items()},
    )
    with server:
        yield server, sinks, device


class Feeder:
    """Readings of a laser at ``frequency_hz`` handed to the server at 1 kHz source time."""

    def __init__(self, server, device, frequency_hz, channel=0):
        self.server, self.device, self.channel = server, device, channel
        self.frequency_hz = frequency_hz
        self.taken = 0
        self.rng = np.random.default_rng(channel)

    def feed(self, readings: int, *, spoil=None) -> None:
        powers = self.device.powers(
            np.full(readings, self.frequency_hz), power_w=POWER_W, noise_w=NOISE_W, rng=self.rng
        )
        if spoil is not None:
            spoil(powers)
        times = 1000.0 + (self.taken + np.arange(readings)) / RATE_HZ  # exact to the ns
        self.taken += readings
        self.server.feed(powers, time_s=times, channel=self.channel)


def _clients(server, count=1):
    return [Client(server.addresses["publish"], server.addresses["control"]) for _ in range(count)]


def test_a_lock_request_is_checked_before_it_changes_anything(served):
    server, sinks, device = served
    (client,) = _clients(server)
    with client:
        for arguments, problem in [
            ({"channel": 2, "setpoint_hz": 193.4e12}, "has no output"),
            ({"channel": 0, "setpoint_hz": 193.4e12}, "actuator_hz_per_v"),
            ({"channel": 0, "setpoint_hz": -1.0, "actuator_hz_per_v": 5e8}, "setpoint_hz"),
            ({"channel": 0, "actuator_hz_per_v": 5e8}, "setpoint_hz or a scan"),
            (
                {
                    "channel": 0,
                    "setpoint_hz": 193.4e12,
                    "actuator_hz_per_v": 5e8,
                    "bandwidth_hz": 1.0,
                    "ki_v_per_hz_s": 1e-8,
                },
                "not both",
            ),
            (
                {
                    "channel": 0,
                    "setpoint_hz": 193.4e12,
                    "actuator_hz_per_v": 5e8,
                    "output_limits_v": [-9, 9],
                },
                "can give -5 to 5 V",
            ),
            (
                {
                    "channel": 0,
                    "scan": {"center_hz": 193.4e12, "amplitude_hz": 1e8},
                    "actuator_hz_per_v": 5e8,
                },
                "scan",
            ),
        ]:
            with pytest.raises(ServiceError, match=problem):
                client.lock(**arguments)
        assert client.lock_status(0)["state"] == "unlocked"
        assert client.lock_status(0)["owner"] is None
        assert sinks[0].written == []


def test_a_lock_belongs_to_its_owner_until_taken_over(served):
    server, sinks, device = served
    first, second = _clients(server, 2)
    feeder = Feeder(server, device, device.center_hz)
    with first, second:
        feeder.feed(50)
        status = first.lock(0, device.center_hz + 2e7, actuator_hz_per_v=5e8, bandwidth_hz=2.0)
        assert status["state"] == "locked" and status["owner"] == first.owner
        assert status["output_v"] == 1.25  # from where the output was: no jump
        with pytest.raises(ServiceError, match="locked by"):
            second.lock(0, device.center_hz, actuator_hz_per_v=5e8)
        with pytest.raises(ServiceError, match="locked by"):
            second.unlock(0)
        assert second.lock_status(0)["owner"] == first.owner
        assert second.lock_status(0)["settings"]["setpoint_hz"] == device.center_hz + 2e7
        taken = second.lock(0, device.center_hz, actuator_hz_per_v=5e8, take_over=True)
        assert taken["owner"] == second.owner
        with pytest.raises(ServiceError, match="locked by"):
            first.unlock(0)
        kept = second.unlock(0)
        assert kept["state"] == "unlocked" and kept["owner"] is None
        assert kept["output_v"] == taken["output_v"]  # unlocking leaves the output


def test_the_lock_drives_the_output_and_its_fields_are_published(served):
    server, sinks, device = served
    (client,) = _clients(server)
    feeder = Feeder(server, device, device.center_hz)
    with client:
        readings = client.readings(0, timeout_s=10)
        assert wait_for(lambda: client.status()["subscribers"], 10)
        client.lock(0, device.center_hz + 5e7, actuator_hz_per_v=5e8, bandwidth_hz=2.0)
        feeder.feed(200)
        got = [next(readings) for _ in range(200)]
    # the laser reads 50 MHz below the setpoint and does not move (no plant): the output
    # climbs at ki * 50 MHz per second, by ki e T per reading from the second on (the
    # first gives the loop its reading interval)
    assert {r.lock_state for r in got} == {1.0}
    errors = np.array([r.lock_error_hz for r in got])
    assert np.all(np.abs(errors + 5e7) < 6 * 14e6)
    outputs = np.array([r.lock_output_v for r in got])
    assert np.all(np.diff(outputs) > 0)
    ki = 2 * np.pi * 2.0 / 5e8
    # (the times went through int64 nanoseconds: the interval to 1e-6)
    assert outputs[-1] - 1.25 == pytest.approx(-ki * errors[1:].sum() / RATE_HZ, rel=1e-6)
    assert sinks[0].written[-1] == pytest.approx(outputs[-1])
    assert {r.lock_setpoint_hz for r in got} == {device.center_hz + 5e7}


def test_flagged_readings_never_move_the_output(served):
    server, sinks, device = served
    (client,) = _clients(server)
    feeder = Feeder(server, device, device.center_hz)
    with client:
        client.lock(0, device.center_hz + 5e7, actuator_hz_per_v=5e8, bandwidth_hz=2.0)
        feeder.feed(20)
        assert wait_for(lambda: client.lock_status(0)["updates"] == 20, 10)
        output = client.lock_status(0)["output_v"]
        written = len(sinks[0].written)

        def nan(powers):
            powers[:] = np.nan

        def off_model(powers):
            powers[:, 0] *= 1.5

        feeder.feed(30, spoil=nan)
        feeder.feed(30, spoil=off_model)
        assert wait_for(lambda: client.lock_status(0)["held_readings"] == 60, 10)
        status = client.lock_status(0)
        assert status["output_v"] == output and status["state"] == "holding"
        assert status["updates"] == 20 and len(sinks[0].written) == written
        feeder.feed(5)
        assert wait_for(lambda: client.lock_status(0)["updates"] == 25, 10)
        assert client.lock_status(0)["state"] == "locked"


def test_a_silent_owner_releases_the_lock_to_hold_not_to_zero(served):
    server, sinks, device = served
    keeper, leaver, other = _clients(server, 3)
    feeder = Feeder(server, device, device.center_hz)
    feeder1 = Feeder(server, device, device.center_hz, channel=1)
    with keeper, other:
        keeper.lock(0, device.center_hz + 5e7, actuator_hz_per_v=5e8, owner_timeout_s=0.4)
        leaver.lock(1, device.center_hz + 5e7, actuator_hz_per_v=5e8, owner_timeout_s=0.4)
        feeder.feed(50)
        feeder1.feed(50)
        assert wait_for(lambda: keeper.lock_status(1)["updates"] == 50, 10)
        output = keeper.lock_status(1)["output_v"]
        leaver.close()  # goes silent
        time.sleep(1.2)
        feeder.feed(50)
        feeder1.feed(50)
        assert wait_for(lambda: keeper.lock_status(0)["updates"] == 100, 10)
        silent = keeper.lock_status(1)
        assert silent["state"] == "holding" and silent["owner"] is None
        assert "owner silent" in silent["alarms"] and silent["output_v"] == output != 0
        alive = keeper.lock_status(0)
        assert alive["state"] == "locked" and alive["owner"] == keeper.owner
        # released: another client locks it without taking it over; the hold ends
        status = other.lock(1, device.center_hz + 5e7, actuator_hz_per_v=5e8)
        assert status["owner"] == other.owner and "owner silent" not in status["alarms"]
        feeder1.feed(5)  # (a lock that had no signal holds until a reading)
        assert wait_for(lambda: other.lock_status(1)["state"] == "locked", 5)


def test_no_signal_holds_the_output_and_alarms(served):
    server, sinks, device = served
    (client,) = _clients(server)
    feeder = Feeder(server, device, device.center_hz)
    with client:
        client.lock(0, device.center_hz + 5e7, actuator_hz_per_v=5e8)
        feeder.feed(30)
        assert wait_for(lambda: client.lock_status(0)["state"] == "holding", 5)
        status = client.lock_status(0)
        assert "no signal" in status["alarms"]
        assert status["updates"] == 30  # the stall moved nothing
        feeder.feed(10)
        assert wait_for(lambda: client.lock_status(0)["state"] == "locked", 5)
        assert "no signal" not in client.lock_status(0)["alarms"]


def test_a_failing_output_holds_and_alarms_until_it_works_again(served):
    server, sinks, device = served
    (client,) = _clients(server)
    feeder = Feeder(server, device, device.center_hz)
    with client:
        client.lock(0, device.center_hz + 5e7, actuator_hz_per_v=5e8)
        feeder.feed(10)
        assert wait_for(lambda: client.lock_status(0)["updates"] == 10, 10)
        sinks[0].failing = True
        feeder.feed(10)
        assert wait_for(lambda: "output failed" in client.lock_status(0)["alarms"], 10)
        status = client.lock_status(0)
        assert (
            status["state"] == "holding"
            and "DAC does not answer" in status["alarms"]["output failed"]
        )
        sinks[0].failing = False
        feeder.feed(10)
        assert wait_for(lambda: client.lock_status(0)["state"] == "locked", 10)
        assert client.lock_status(0)["alarm_counts"]["output failed"] == 1


def test_the_lock_fields_start_a_new_log_segment_read_back_in_order(served, tmp_path):
    server, sinks, device = served
    (client,) = _clients(server)
    feeder = Feeder(server, device, device.center_hz)
    with client:
        feeder.feed(10)
        assert wait_for(lambda: client.status()["log"]["rows"] == 10, 10)
        client.lock(0, device.center_hz, actuator_hz_per_v=5e8)
        feeder.feed(10)
        assert wait_for(lambda: client.status()["log"]["rows"] == 20, 10)
    server.stop()
    log = read_log(tmp_path, channel=0)
    assert log["sequence"].to_pylist() == list(range(20))
    assert log["lock_state"].to_pylist() == [None] * 10 + [1.0] * 10


def test_a_scan_set_through_the_client_moves_the_published_setpoint(served):
    """A triangle of 100 MHz and 0.2 s from the client: each reading's published setpoint is
    the scan at its source time from the first locked reading, and the settings say so."""
    server, _, device = served
    (client,) = _clients(server)
    feeder = Feeder(server, device, device.center_hz)
    scan = Scan(device.center_hz, amplitude_hz=1e8, period_s=0.2, shape="triangle")
    with client:
        readings = client.readings(0, timeout_s=10)
        assert wait_for(lambda: client.status()["subscribers"], 10)
        status = client.lock(
            0,
            scan={"center_hz": device.center_hz, "amplitude_hz": 1e8, "period_s": 0.2},
            actuator_hz_per_v=5e8,
            bandwidth_hz=2.0,
        )
        assert status["settings"]["setpoint_hz"] is None
        assert status["settings"]["scan"]["shape"] == "triangle"
        feeder.feed(300)
        got = [next(readings) for _ in range(300)]
    times = np.array([r.source_time_ns for r in got]) * 1e-9
    setpoints = np.array([r.lock_setpoint_hz for r in got])
    expected = np.array([scan.at(t) for t in times - times[0]])
    assert np.max(np.abs(setpoints - expected)) < 1.0  # Hz: the same function of time
    assert np.ptp(setpoints) == pytest.approx(2e8, rel=0.02)  # +-100 MHz over 1.5 periods
