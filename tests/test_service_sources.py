"""Sources of `wavemeter serve`: TCP lines (a stall turns the channel to "no signal" and
back; malformed lines become INVALID readings, counted), standard input with a channel
column, a header the calibration cannot read, and ``Server.feed`` from lab code."""

from __future__ import annotations

import socket
import subprocess
import sys
import time

import numpy as np
import pytest

import wavemeter as wm  # noqa: E402
from wavemeter.service import Client, Server  # noqa: E402

from ._service import (
    EPHEMERAL,
    addresses_of,
    feed_lines,
    lines_of,
    make_meter,
    serving,
    source_port,
    subscribed,
    tcp_service,
    wait_for,
)

INVALID = int(wm.ReadingFlag.INVALID)


@pytest.fixture(scope="module")
def meter(tmp_path_factory):
    return make_meter(tmp_path_factory)


@pytest.mark.slow
def test_a_stalled_source_has_no_signal_within_the_timeout_and_back(meter):
    device, _ = meter
    rng = np.random.default_rng(2)
    with tcp_service(meter, "--signal-timeout", "0.3s") as service:
        with Client(**addresses_of(service)) as client:

            def status():
                return client.status()["channels"][0]["status"]

            with feed_lines(source_port(service), lines_of(device, 50, rng)) as connection:
                assert wait_for(lambda: status() == "ok", 10)
                stalled = time.monotonic()
                assert wait_for(lambda: status() == "no signal", 5)
                # within the timeout (0.3 s) and the watch's period, plus the request's trip
                assert time.monotonic() - stalled < 1.5
                connection.sendall(("\n".join(lines_of(device, 5, rng)) + "\n").encode())
                assert wait_for(lambda: status() == "ok", 5)


@pytest.mark.slow
def test_malformed_lines_become_invalid_readings_counted(meter):
    device, _ = meter
    rng = np.random.default_rng(3)
    good = lines_of(device, 6, rng)
    bad = ["1.0,2.0", "0.3,abc,0.2", "nan,0.2,0.3", "0,0,0", "1,2,3,4,5"]
    lines = [good[0], *bad[:3], good[1], good[2], *bad[3:], *good[3:]]
    with tcp_service(meter) as service, Client(**addresses_of(service)) as client:
        readings = subscribed(client)
        with feed_lines(source_port(service), lines):
            got = [next(readings) for _ in lines]
            status = client.status()
    assert [r.sequence for r in got] == list(range(len(lines)))
    flags = [r.flags & INVALID for r in got]
    assert flags == [INVALID if line in bad else 0 for line in lines]
    assert all(np.isnan(r.frequency_hz) for r in got if r.flags & INVALID)
    assert status["lines"]["invalid"] == len(bad) and status["lines"]["lines"] == len(lines)
    assert status["channels"][0]["flag_counts"]["INVALID"] == len(bad)


@pytest.mark.slow
def test_standard_input_with_a_channel_column(meter):
    device, folder = meter
    rng = np.random.default_rng(4)
    rows = lines_of(device, 40, rng)
    text = "P1_mW,P2_mW,P3_mW,laser\n" + "".join(
        f"{row},{k % 3 if k != 7 else 'x'}\n" for k, row in enumerate(rows)
    )
    args = [str(folder / "chip.wmcal.json"), "--channel-column", "laser", *EPHEMERAL]
    with serving(args, stdin=subprocess.PIPE) as service:
        with Client(**addresses_of(service)) as client:
            readings = subscribed(client)
            service.process.stdin.write(text)
            service.process.stdin.flush()
            got = [next(readings) for _ in range(39)]
            status = client.status()
    by_channel = {c: [r.sequence for r in got if r.channel == c] for c in (0, 1, 2)}
    assert sorted(by_channel) == [0, 1, 2]
    for numbers in by_channel.values():
        assert numbers == list(range(len(numbers)))
    assert status["lines"]["unroutable"] == 1 and len(got) == 39


@pytest.mark.slow
def test_a_tcp_connection_whose_header_the_calibration_cannot_read_gets_an_error(meter):
    with tcp_service(meter) as service:
        with socket.create_connection(("127.0.0.1", source_port(service))) as connection:
            connection.sendall(b"P1_mW,P2_mW\n0.1,0.2\n")
            answer = connection.makefile().readline()
        assert answer.startswith("error: ") and "ports" in answer
        with Client(**addresses_of(service)) as client:  # the service goes on
            assert client.status()["service"] == "wavemeter"


def test_server_feed_publishes_lab_readings():
    device, calibration = _meter()
    rng = np.random.default_rng(5)
    truth = device.center_hz + rng.uniform(-5e9, 5e9, 30)
    powers = device.powers(truth, power_w=1e-3, noise_w=5e-7, rng=rng)
    server = Server(
        calibration, publish="tcp://127.0.0.1:0", control="tcp://127.0.0.1:0", http=None
    )
    with server, Client(server.addresses["publish"], server.addresses["control"]) as client:
        readings = subscribed(client, channel=2)
        server.feed(powers[:10], channel=2)
        server.feed(powers[10], time_s=1.7e9, channel=2)
        server.feed(powers[11:], channel=2)
        got = [next(readings) for _ in range(30)]
        with pytest.raises(wm.InputError, match="ports"):
            server.feed(powers[:, :2])
    assert [r.sequence for r in got] == list(range(30))
    assert got[10].source_time_ns == 1_700_000_000_000_000_000
    error = np.array([r.frequency_hz for r in got]) - truth
    std = np.array([r.frequency_std_hz for r in got])
    assert np.all(np.abs(error) < 5 * std)


def _meter():
    from wavemeter.service.simulated import simulated_meter

    return simulated_meter(7)


class _Offset:
    """A processor (as a lock would be): adds each reading's offset from a setpoint."""

    outputs = {"offset_hz": "Hz"}

    def __init__(self, setpoint_hz: float):
        self.setpoint_hz = setpoint_hz
        self.seen = 0
        self.statuses = []

    def observe(self, channel, columns):
        self.seen += len(columns["sequence"])
        return {"offset_hz": columns["frequency_hz"] - self.setpoint_hz}

    def status_changed(self, channel, status):
        self.statuses.append(status)


def test_a_channel_processor_sees_every_reading_and_its_output_is_published(tmp_path):
    import asyncio

    from wavemeter.service import AsyncClient, read_log

    device, calibration = _meter()
    powers = device.powers(np.full(20, device.center_hz), power_w=1e-3, noise_w=5e-7, rng=6)
    processor = _Offset(device.center_hz)
    local = "tcp://127.0.0.1:0"
    server = Server(
        calibration, publish=local, control=local, http=None, log=tmp_path, signal_timeout_s=0.3
    )
    server.channel(0).processors.append(processor)
    with server:
        client = AsyncClient(server.addresses["publish"], server.addresses["control"])

        async def read():
            readings = client.readings(timeout_s=10)
            first = asyncio.ensure_future(readings.__anext__())
            while not (await client.status())["subscribers"]:
                await asyncio.sleep(0.05)
            server.feed(powers)
            got = [await first] + [await readings.__anext__() for _ in range(19)]
            await readings.aclose()
            return got

        got = asyncio.run(read())
        client.close()
        assert wait_for(lambda: "no signal" in processor.statuses, 5)
    assert processor.seen == 20 and processor.statuses[:1] == ["ok"]
    offsets = np.array([r.offset_hz for r in got])
    np.testing.assert_allclose(offsets, [r.frequency_hz - device.center_hz for r in got])
    assert np.all(np.abs(offsets) < 5 * np.array([r.frequency_std_hz for r in got]))
    assert "offset_hz" in read_log(tmp_path).column_names


@pytest.mark.slow
def test_a_followed_file(meter, tmp_path):
    device, folder = meter
    rng = np.random.default_rng(8)
    path = tmp_path / "readings.csv"
    path.write_text(
        "P1_mW,P2_mW,P3_mW\n" + "".join(f"{line}\n" for line in lines_of(device, 5, rng))
    )
    args = [str(folder / "chip.wmcal.json"), "--source", str(path), "--follow", *EPHEMERAL]
    with serving(args) as service, Client(**addresses_of(service)) as client:
        assert wait_for(lambda: client.status()["channels"][0]["readings"] == 5, 10)
        with path.open("a") as appended:
            appended.write("".join(f"{line}\n" for line in lines_of(device, 7, rng)))
        assert wait_for(lambda: client.status()["channels"][0]["readings"] == 12, 10)
        assert client.latest(0)["sequence"] == 11


@pytest.mark.slow
def test_standard_input_whose_header_the_calibration_cannot_read_is_an_error_line(meter):
    _, folder = meter
    result = subprocess.run(
        [sys.executable, "-m", "wavemeter", "serve", str(folder / "chip.wmcal.json"), *EPHEMERAL],
        input="P1_mW,P2_mW\n0.1,0.2\n",
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("error: <stdin>: ") and "ports" in last and "--ports" in last


@pytest.mark.slow
def test_with_a_token_a_tcp_source_must_send_it_first(meter):
    device, _ = meter
    rng = np.random.default_rng(9)
    with tcp_service(meter, "--token", "s3cret") as service:
        port = source_port(service)
        with socket.create_connection(("127.0.0.1", port)) as connection:
            connection.sendall(b"P1_mW,P2_mW,P3_mW\n0.1,0.2,0.3\n")
            answer = connection.makefile().readline()
        assert answer.startswith("error: refused") and "#token" in answer
        with Client(**addresses_of(service), token="s3cret") as client:
            with socket.create_connection(("127.0.0.1", port)) as connection:
                body = "#token s3cret\nP1_mW,P2_mW,P3_mW\n" + "\n".join(lines_of(device, 4, rng))
                connection.sendall((body + "\n").encode())
                assert wait_for(lambda: client.status()["channels"], 10)
                assert wait_for(lambda: client.status()["channels"][0]["readings"] == 4, 10)
