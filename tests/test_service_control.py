"""The control socket of `wavemeter serve`: status, channels, latest, the calibration,
reload (a good file swaps in without losing a reading; a bad one keeps the old), names;
a malformed request changes nothing; tokens and non-local binds."""

from __future__ import annotations

import json
import subprocess
import sys
import urllib.error
import urllib.request

import numpy as np
import pytest
import zmq

from wavemeter.service import Client, ServiceError  # noqa: E402

from ._service import (
    addresses_of,
    feed_lines,
    lines_of,
    make_meter,
    source_port,
    tcp_service,
    wait_for,
)

#: each test starts real `wavemeter serve` processes (seconds each): not the fast tier
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def meter(tmp_path_factory):
    return make_meter(tmp_path_factory)


def test_requests_and_reload(meter):
    device, folder = meter
    rng = np.random.default_rng(1)
    with tcp_service(meter) as service, Client(**addresses_of(service)) as client:
        with feed_lines(source_port(service), lines_of(device, 200, rng)):
            assert wait_for(lambda: client.latest(0), 10)
            status = client.status()
            assert status["channels"][0]["readings"] >= 1
            assert client.request("channels") == [
                {"channel": 0, "name": "ch0", "topic": "ch/0/", "status": "ok"}
            ]
            summary = client.request("calibration")
            assert summary["method"] == "learned" and summary["ports"] == ["p1", "p2", "p3"]
            assert summary["summary"]["values"]["fsr_hz"]["value"] > 4e10
            latest = client.latest(0)
            assert set(latest) >= {"channel", "sequence", "frequency_hz", "flags"}
            # a bad file: the error comes back, the calibration in force stays
            with pytest.raises(ServiceError, match="corrupt.wmcal.json"):
                client.request("reload", path=str(folder / "corrupt.wmcal.json"))
            with pytest.raises(ServiceError, match="missing.wmcal.json"):
                client.request("reload", path=str(folder / "missing.wmcal.json"))
            assert client.status()["calibration"]["path"].endswith("chip.wmcal.json")
            # a good file swaps in while readings flow
            done = client.request("reload", path=str(folder / "other.wmcal.json"))
            assert done["path"].endswith("other.wmcal.json")
            assert client.status()["calibration"]["path"].endswith("other.wmcal.json")
            names = client.request("channel_names", names={"0": "Ti:Sa"})
            assert names == {"0": "Ti:Sa"} and client.request("channels")[0]["name"] == "Ti:Sa"
        # no reading lost over the swap: the readings are numbered 0 .. 199
        assert wait_for(lambda: client.status()["channels"][0]["readings"] == 200, 10)
        assert client.latest(0)["sequence"] == 199


def test_a_malformed_request_changes_nothing(meter):
    with tcp_service(meter) as service, Client(**addresses_of(service)) as client:
        before = client.status()
        for name, arguments, problem in [
            ("bogus", {}, "unknown request 'bogus'"),
            ("reload", {"file": "x"}, "request 'reload'"),
            ("latest", {"channel": 5}, "no channel 5"),
            ("channel_names", {"names": {"999": "x"}}, "channel '999'"),
            ("channel_names", {"names": {"0": ""}}, "name ''"),
            ("channel_names", {"names": ["a"]}, "names must be an object"),
        ]:
            with pytest.raises(ServiceError, match=problem):
                client.request(name, **arguments)
        # bytes that are not JSON, and JSON that is not an object
        with zmq.Context() as context, context.socket(zmq.REQ) as raw:
            raw.connect(service.addresses["control"])
            for body in (b"\xff\x00 not json", b"[1, 2]", b'{"request": 3}'):
                raw.send(body)
                assert raw.poll(5000)
                reply = json.loads(raw.recv())
                assert reply["ok"] is False and reply["error"]
        after = client.status()
        assert after["calibration"] == before["calibration"]
        assert client.request("channel_names") == {}
        assert after["control"]["errors"] == before["control"]["errors"] + 9


def test_a_token_guards_control_subscriptions_and_http(meter):
    with tcp_service(meter, "--token", "s3cret") as service:
        addresses = addresses_of(service)
        with Client(**addresses) as client:
            with pytest.raises(ServiceError, match="token"):
                client.status()
            with pytest.raises(ServiceError, match="token"):
                next(client.readings(timeout_s=5))
        with Client(**addresses, token="wrong") as client, pytest.raises(ServiceError):
            client.status()
        with Client(**addresses, token="s3cret") as client:
            assert client.status()["service"] == "wavemeter"
        url = service.addresses["http"]
        for page in ("metrics", "", "api/status", "ws"):
            with pytest.raises(urllib.error.HTTPError) as refused:
                urllib.request.urlopen(url + page, timeout=10)
            assert refused.value.code == 401
        with urllib.request.urlopen(url + "?token=s3cret", timeout=10) as answer:
            assert b"wavemeter live" in answer.read()
        with urllib.request.urlopen(url + "metrics?token=s3cret", timeout=10) as answer:
            assert answer.status == 200


@pytest.mark.parametrize(
    "option", ["--publish tcp://0.0.0.0:0", "--control tcp://192.0.2.1:5561", "--http *:8560"]
)
def test_a_non_local_bind_without_a_token_is_refused(option):
    result = subprocess.run(
        [sys.executable, "-m", "wavemeter", "serve", "--simulate", *option.split()],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and "token" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
