"""The service's sockets in this process (fast tier): a TCP line source, a followed file, the
plain PUB socket, the publish socket's order of sending, and the HTTP side of a
:class:`~wavemeter.service.Server` started in a thread on 127.0.0.1 with ephemeral ports.
The same paths through a real ``wavemeter serve`` process are tested (slow tier) in
``test_service_sources.py``, ``test_service_pub.py`` and ``test_service_http.py``."""

from __future__ import annotations

import json
import socket
import urllib.error
import urllib.request

import numpy as np
import pytest

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

import zmq  # noqa: E402
from prometheus_client.parser import text_string_to_metric_families  # noqa: E402

import wavemeter as wm  # noqa: E402
from wavemeter.service import Client, Server, decode_message  # noqa: E402
from wavemeter.service.encoding import channel_topic  # noqa: E402
from wavemeter.service.lines import LineParser  # noqa: E402
from wavemeter.service.publisher import Publisher, Subscriber  # noqa: E402
from wavemeter.service.simulated import NOISE_W, POWER_W, simulated_meter  # noqa: E402
from wavemeter.service.sources import TcpLineSource, ThreadLineSource  # noqa: E402

from ._service import wait_for  # noqa: E402
from .helpers import reading_batch  # noqa: E402

LOCAL = "tcp://127.0.0.1:0"
INVALID = int(wm.ReadingFlag.INVALID)
HEADER = "P1_mW,P2_mW,P3_mW"


@pytest.fixture(scope="module")
def meter():
    return simulated_meter(7)


def _lines(device, frequencies_hz, rng) -> list[str]:
    powers_mw = device.powers(frequencies_hz, power_w=POWER_W, noise_w=NOISE_W, rng=rng) * 1e3
    return [",".join(repr(float(p)) for p in row) for row in powers_mw]


def _subscribed(address: str):
    """A SUB socket on channel 0 and heartbeats, returned once its subscription is in force
    (a heartbeat came)."""
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    sub.setsockopt(zmq.RCVTIMEO, 10_000)
    sub.connect(address)
    for topic in (b"ch/0/", b"heartbeat/"):
        sub.setsockopt(zmq.SUBSCRIBE, topic)
    assert sub.recv_multipart()[0] in (b"ch/0/", b"heartbeat/")
    return sub


def _received(sub, last_sequence: int) -> dict[str, np.ndarray]:
    """Channel 0's readings of a SUB socket up to ``last_sequence`` (other messages
    skipped), their columns joined."""
    parts: dict[str, list] = {}
    while not parts or parts["sequence"][-1][-1] < last_sequence:
        topic, body = sub.recv_multipart()
        if topic != b"ch/0/":
            continue
        batch = decode_message(body)[1]
        for name, values in batch.columns.items():
            parts.setdefault(name, []).append(np.asarray(values))
    return {name: np.concatenate(values) for name, values in parts.items()}


def _get(url: str, token: str | None = None) -> tuple[int, bytes]:
    request = urllib.request.Request(url)
    if token is not None:
        request.add_header("Authorization", f"Bearer {token}")
    try:
        with urllib.request.urlopen(request, timeout=10) as answer:
            return answer.status, answer.read()
    except urllib.error.HTTPError as refused:
        return refused.code, refused.read()


def test_tcp_lines_reach_a_plain_sub_socket_with_a_malformed_line_invalid(meter):
    device, calibration = meter
    rng = np.random.default_rng(11)
    truth_hz = device.center_hz + rng.uniform(-5e9, 5e9, 12)
    lines = _lines(device, truth_hz, rng)
    lines[4] = "0.1,oops,0.2"
    server = Server(calibration, publish=LOCAL, control=LOCAL, http=None, pub=LOCAL)
    source = TcpLineSource(server, "127.0.0.1", 0, LineParser)
    server.add_source(source)
    with server:
        sub = _subscribed(server.addresses["pub"])
        with Client(server.addresses["publish"], server.addresses["control"]) as client:
            with socket.create_connection(("127.0.0.1", source.port)) as connection:
                connection.sendall(("\n".join([HEADER, *lines]) + "\n").encode())
                columns = _received(sub, len(lines) - 1)
            status = wait_for(lambda: (s := client.status())["lines"]["lines"] >= 12 and s, 10)
        sub.close()
    np.testing.assert_array_equal(columns["sequence"], np.arange(len(lines)))
    flags = columns["flags"].astype(int)
    assert flags[4] & INVALID and np.isnan(columns["frequency_hz"][4])
    good = np.arange(len(lines)) != 4
    assert not np.any(flags[good] & INVALID)
    error_hz = columns["frequency_hz"][good] - truth_hz[good]
    assert np.all(np.abs(error_hz) < 5 * columns["frequency_std_hz"][good])
    assert status["lines"]["invalid"] == 1


def test_a_tcp_header_the_calibration_cannot_read_gets_an_error_line(meter):
    _, calibration = meter
    server = Server(calibration, publish=LOCAL, control=LOCAL, http=None)
    source = TcpLineSource(server, "127.0.0.1", 0, LineParser)
    server.add_source(source)
    with server:
        with socket.create_connection(("127.0.0.1", source.port)) as connection:
            connection.sendall(b"P1_mW,P2_mW\n0.1,0.2\n")
            answer = connection.makefile().readline()
        assert answer.startswith("error: ") and "ports" in answer
        assert server.failure is None  # the service goes on


def test_a_file_source_publishes_every_line(meter, tmp_path):
    device, calibration = meter
    rng = np.random.default_rng(12)
    truth_hz = device.center_hz + rng.uniform(-5e9, 5e9, 20)
    path = tmp_path / "readings.csv"
    path.write_text("\n".join([HEADER, *_lines(device, truth_hz, rng)]) + "\n")
    server = Server(calibration, publish=LOCAL, control=LOCAL, http=None, pub=LOCAL)
    server.add_source(ThreadLineSource(server, LineParser(str(path)), path, follow=True))
    with server:
        sub = _subscribed(server.addresses["pub"])
        with path.open("a") as more:  # what is appended to a followed file is read too
            more.write("\n".join(_lines(device, truth_hz[:5], rng)) + "\n")
        # the subscription may have come after the first lines: the appended ones are whole
        columns = _received(sub, 24)
        sub.close()
    np.testing.assert_array_equal(columns["sequence"][-5:], np.arange(20, 25))
    error_hz = columns["frequency_hz"][-5:] - truth_hz[:5]
    assert np.all(np.abs(error_hz) < 5 * columns["frequency_std_hz"][-5:])


def test_metrics_status_and_the_dashboard_over_http(meter):
    device, calibration = meter
    powers_w = device.powers(
        np.full(30, device.center_hz), power_w=POWER_W, noise_w=NOISE_W, rng=13
    )
    server = Server(calibration, publish=LOCAL, control=LOCAL, http="127.0.0.1:0")
    with server:
        base = server.addresses["http"]
        server.feed(powers_w, channel=1)
        status = wait_for(
            lambda: (s := json.loads(_get(base + "api/status")[1])) and s["channels"] and s, 10
        )
        code, text = _get(base + "metrics")
        page_code, page = _get(base)
    assert code == 200 and page_code == 200 and b"<html" in page.lower()
    families = {family.name: family for family in text_string_to_metric_families(text.decode())}
    readings = [
        sample
        for family in families.values()
        for sample in family.samples
        if sample.name.endswith("readings_total") and sample.labels.get("channel") == "1"
    ]
    assert readings and readings[0].value == 30
    assert [c["channel"] for c in status["channels"]] == [1]


def test_with_a_token_http_requests_without_it_are_refused(meter):
    _, calibration = meter
    server = Server(calibration, publish=LOCAL, control=LOCAL, http="127.0.0.1:0", token="t0k")
    with server:
        base = server.addresses["http"]
        refused, _ = _get(base + "metrics")
        wrong, _ = _get(base + "metrics", token="other")
        allowed, text = _get(base + "metrics", token="t0k")
    assert (refused, wrong, allowed) == (401, 401, 200)
    assert list(text_string_to_metric_families(text.decode()))


def test_a_subscriber_whose_queue_was_full_is_sent_to_last():
    context = zmq.Context()
    publisher = Publisher(context, LOCAL)
    sent, stopped = [], b"stopped"

    def send(frames, flags=0, copy=True):  # a stopped subscriber's queue is full
        sent.append(frames[0])
        if frames[0] == stopped:
            raise zmq.Again()

    publisher._send = send
    dropped = []
    publisher.on_dropped = lambda channel, readings: dropped.append(readings)
    topic = channel_topic(3)
    for identity in (stopped, b"running-1", b"running-2"):
        publisher.subscribers[identity] = Subscriber(identity, (topic,))
    try:
        for first in (0, 5, 10):
            publisher.publish(reading_batch(first))
    finally:
        publisher.socket.close(linger=0)
        context.term()
    assert sent[:3] == [stopped, b"running-1", b"running-2"]  # not yet known to be full
    assert sent[3:] == [b"running-1", b"running-2", stopped] * 2
    assert dropped == [5, 5, 5] and publisher.subscribers[stopped].dropped_readings == 15
