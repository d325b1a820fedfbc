"""`wavemeter serve --simulate` publishes to clients in other processes: consecutive
sequences, the declared fields, subscribers that cannot slow each other, and clients that
rejoin a restarted service by themselves."""

from __future__ import annotations

import json
import signal
import time

import numpy as np
import pytest

from wavemeter.service import Client  # noqa: E402  (after the skip of _service)

from ._service import EPHEMERAL, SUBSCRIBER, child, free_port, sequences, serving, wait_for

#: each test starts real `wavemeter serve` processes (seconds each): not the fast tier
pytestmark = pytest.mark.slow


def _batches(process) -> tuple[list[dict], dict]:
    """The batch lines and the last (summary) line of a subscriber child."""
    out, err = process.communicate(timeout=60)
    lines = [json.loads(line) for line in out.splitlines() if line.strip()]
    assert lines and "missed" in lines[-1], err[-2000:]
    return [line for line in lines if "run" in line], lines[-1]


def test_simulate_publishes_consecutive_readings_to_a_client_in_this_process():
    with serving(["--simulate", "--channels", "2", *EPHEMERAL]) as service:
        with Client(service.addresses["publish"], service.addresses["control"]) as client:
            readings = []
            for reading in client.readings(timeout_s=10):
                readings.append(reading)
                if len(readings) == 600:
                    break
            missed = client.missed
    assert missed == 0
    by_channel = {0: [], 1: []}
    for reading in readings:
        by_channel[reading.channel].append(reading)
    for channel, mine in by_channel.items():
        numbers = [r.sequence for r in mine]
        assert numbers == list(range(numbers[0], numbers[0] + len(numbers))), channel
        # every field of the record, as attributes
        for r in mine:
            assert r.source_time_ns <= r.time_ns
            assert r.flags == 0
        # the truth beside the measurement: the error is the meter's noise (Table 1 at
        # 1 mW: ~10-15 MHz per reading); its z-scores have about unit spread
        z = np.array([(r.frequency_hz - r.true_frequency_hz) / r.frequency_std_hz for r in mine])
        assert abs(np.mean(z)) < 0.5 and 0.7 < np.std(z) < 1.4
    # the switch schedule: readings alternate between the two channels' lasers
    truths = [np.median([r.true_frequency_hz for r in by_channel[c]]) for c in (0, 1)]
    assert abs(truths[1] - truths[0]) > 1e9


def test_three_subscribers_one_stopped_the_others_lose_nothing():
    args = ["--simulate", "--rate", "2kHz", "--hwm", "50", *EPHEMERAL]
    with serving(args) as service:
        publish, control = service.addresses["publish"], service.addresses["control"]
        with (
            child(SUBSCRIBER, publish, control, "6") as first,
            child(SUBSCRIBER, publish, control, "6") as second,
            child(SUBSCRIBER, publish, control, "30") as stopped,
        ):
            for process in (first, second, stopped):
                assert json.loads(process.stdout.readline())["started"]
            with Client(publish, control) as client:
                assert wait_for(lambda: len(client.status()["subscribers"]) == 3, 10)
                stopped.send_signal(signal.SIGSTOP)
                # the stopped one's queue fills; its messages are dropped, counted
                dropped = wait_for(
                    lambda: max(s["dropped_messages"] for s in client.status()["subscribers"]),
                    20,
                )
                status = client.status()  # the two others are still reading
                assert dropped, status["subscribers"]
                results = [_batches(process) for process in (first, second)]
            stopped.send_signal(signal.SIGCONT)
    for batches, summary in results:
        assert summary["missed"] == 0
        (numbers,) = sequences(batches).values()
        assert numbers == list(range(numbers[0], numbers[0] + len(numbers)))
        assert len(numbers) > 1000  # of 12000 taken in its 6 s at 2 kHz
    counts = sorted(s["dropped_messages"] for s in status["subscribers"])
    assert len(counts) == 3 and counts[:2] == [0, 0] and counts[2] > 0
    assert status["channels"][0]["dropped"] > 0 and status["dropped_messages"] == counts[2]


#: a subscriber that reads until it has 200 readings of a service run after a restart
REJOINING = """
import json, sys
from wavemeter.service import Client
client = Client(sys.argv[1], sys.argv[2])
batches = client.batches(timeout_s=60)
print(json.dumps({"started": True}), flush=True)
after = 0
for batch in batches:
    print(json.dumps({"run": batch.run, "channel": batch.channel,
                      "first": int(batch.columns["sequence"][0]), "count": len(batch)}),
          flush=True)
    after += len(batch) if client.restarts else 0
    if after >= 200:
        break
print(json.dumps({"missed": client.missed, "restarts": client.restarts}), flush=True)
"""


def test_a_client_rejoins_a_restarted_service_by_itself():
    publish = f"tcp://127.0.0.1:{free_port()}"
    control = f"tcp://127.0.0.1:{free_port()}"
    args = ["--simulate", "--publish", publish, "--control", control, "--http", "off"]
    with child(REJOINING, publish, control) as subscriber:
        assert json.loads(subscriber.stdout.readline())["started"]
        with serving(args):
            time.sleep(2)
        time.sleep(0.5)  # the service is gone for a while
        with serving(args):
            batches, summary = _batches(subscriber)
    runs = list(dict.fromkeys(batch["run"] for batch in batches))
    assert len(runs) == 2 and summary["restarts"] == 1
    for numbers in sequences(batches).values():  # each run: consecutive, from where joined
        assert numbers == list(range(numbers[0], numbers[0] + len(numbers)))
    assert sum(batch["count"] for batch in batches if batch["run"] == runs[0]) > 100
