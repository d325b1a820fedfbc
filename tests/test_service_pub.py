"""`wavemeter serve --pub`: a plain ZeroMQ SUB socket reads the readings (consecutive
sequences, the documented messages); a stopped SUB subscriber loses its own messages only,
and sees them as gaps; with a token, only a subscriber that logs in gets anything."""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest
import zmq

from wavemeter.service import Client, decode_message  # noqa: E402

from ._service import EPHEMERAL, UNTIL, child, serving, stop_at, wait_for

#: each test starts real `wavemeter serve` processes (seconds each): not the fast tier
pytestmark = pytest.mark.slow

PUB = ["--pub", "tcp://127.0.0.1:0"]


def _pub_address(service) -> str:
    assert wait_for(lambda: "pub" in service.addresses, 10), service.stderr
    return service.addresses["pub"]


def test_three_sub_sockets_one_stopped_the_others_lose_nothing():
    args = ["--simulate", "--rate", "10kHz", "--hwm", "50", *PUB, *EPHEMERAL]
    with serving(args) as service:
        pub, control = _pub_address(service), service.addresses["control"]
        with (
            child(UNTIL, "sub", pub, control, "-") as first,
            child(UNTIL, "sub", pub, control, "-") as second,
            child(UNTIL, "sub", pub, control, "-") as stopped,
            Client(service.addresses["publish"], control) as client,
        ):
            for process in (first, second, stopped):
                assert json.loads(process.stdout.readline())["started"]
            stopped.send_signal(signal.SIGSTOP)
            began = client.status()["channels"][0]["next_sequence"]
            # ZeroMQ does not report a PUB socket's drops; stopped long enough to lose some:
            # its queue (50 messages) and both kernel socket buffers (256 KiB each, doubled
            # by Linux) hold some 15,000 readings (about 80 bytes each in blocks of 5)
            after = began + 60_000
            assert wait_for(lambda: client.status()["channels"][0]["next_sequence"] > after, 60), (
                client.status()["channels"]
            )
            results = [stop_at(process, after) for process in (first, second)]
            stopped.send_signal(signal.SIGCONT)
            resumed = stop_at(stopped, after + 10_000)
    for result in results:  # every reading from before the stop to after it
        assert result["missed"] == 0 and result["first"] <= began and result["last"] >= after
        assert result["count"] == result["last"] - result["first"] + 1
    assert resumed["first"] <= began and resumed["missed"] > 0  # lost its own: gaps


def test_a_sub_socket_gets_readings_and_heartbeats_and_a_token_is_a_plain_login():
    args = ["--simulate", "--token", "s3cret", *PUB, *EPHEMERAL]
    with serving(args) as service:
        pub = _pub_address(service)
        context = zmq.Context()
        try:
            guest = context.socket(zmq.SUB)
            member = context.socket(zmq.SUB)
            member.plain_username, member.plain_password = b"wavemeter", b"s3cret"
            for socket in (guest, member):
                socket.setsockopt(zmq.LINGER, 0)
                socket.setsockopt(zmq.SUBSCRIBE, b"")
                socket.connect(pub)
            kinds = {}
            wanted = {"wavemeter.readings", "wavemeter.heartbeat"}
            while not wanted <= set(kinds) and member.poll(10_000):
                topic, body = member.recv_multipart()
                kinds[decode_message(body)[0]] = topic
            # the guest, refused by the authenticator, got nothing in all that time
            assert not guest.poll(500)
        finally:
            context.destroy(linger=0)
    # (status messages come when a channel's status changes: maybe before it connected)
    assert kinds["wavemeter.readings"] == b"ch/0/"
    assert kinds["wavemeter.heartbeat"] == b"heartbeat/"
    assert kinds.get("wavemeter.status", b"status/") == b"status/"


def test_a_non_local_pub_without_a_token_is_refused():
    command = [sys.executable, "-m", "wavemeter", "serve", "--simulate", "--http", "off"]
    result = subprocess.run(
        [*command, "--pub", "tcp://0.0.0.0:0"], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2
    assert result.stderr.startswith("error: the pub address") and "token" in result.stderr
