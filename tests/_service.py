"""Starting and stopping real ``wavemeter serve`` processes (and client processes) in tests.

Every process started here is stopped by the context manager that started it (SIGTERM,
then SIGKILL after a timeout), whatever the test does.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

#: stderr line the service prints once bound
READY = re.compile(r"publish (?P<publish>[^\s,]+), control (?P<control>[^\s,]+)")
EPHEMERAL = [
    "--publish",
    "tcp://127.0.0.1:0",
    "--control",
    "tcp://127.0.0.1:0",
    "--http",
    "127.0.0.1:0",
]


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now (for a service restarted on the same port)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class Serve:
    """A ``wavemeter serve`` child: its addresses and its stderr lines."""

    def __init__(self, args, *, stdin=None, env=None):
        command = [sys.executable, "-m", "wavemeter", "serve", *args]
        self.process = subprocess.Popen(
            command,
            stdin=stdin,
            stderr=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            text=True,
            env={**os.environ, **(env or {})},
        )
        self.lines: list[str] = []
        self.addresses: dict[str, str] = {}
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.process.stderr:
            self.lines.append(line.rstrip("\n"))
            match = READY.search(line)
            if match:
                self.addresses.update(match.groupdict())
            if line.startswith("dashboard: "):
                self.addresses["http"] = line.split()[1]

    def wait_ready(self, timeout_s: float = 30.0) -> Serve:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not self.addresses.get("publish"):
            if self.process.poll() is not None:
                break
            time.sleep(0.02)
        if "publish" not in self.addresses:
            self.stop()
            raise AssertionError(f"the service did not start: {self.stderr}")
        wait_for(lambda: "http" in self.addresses, 0.5)  # the line after, if any
        return self

    @property
    def stderr(self) -> str:
        return "\n".join(self.lines)

    def stop(self, sig=signal.SIGTERM, timeout_s: float = 20.0) -> int:
        """Send ``sig`` and wait; SIGKILL if it has not ended in ``timeout_s``."""
        if self.process.poll() is None:
            self.process.send_signal(sig)
            try:
                self.process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._reader.join(5)
        return self.process.returncode


@contextlib.contextmanager
def serving(args, **kwargs):
    """A started service; stopped (SIGTERM, then SIGKILL) on the way out."""
    service = Serve(args, **kwargs)
    try:
        yield service.wait_ready()
    finally:
        service.stop()
        if service.process.stdin is not None:
            service.process.stdin.close()


@contextlib.contextmanager
def child(code: str, *args):
    """A Python child running ``code`` (stdout lines readable); killed on the way out."""
    process = subprocess.Popen(
        [sys.executable, "-c", code, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        yield process
    finally:
        if process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                process.send_signal(signal.SIGCONT)
            process.kill()
        process.wait()
        process.stdout.close()
        process.stderr.close()


def wait_for(predicate, timeout_s: float = 10.0, every_s: float = 0.05):
    """Poll ``predicate`` until it returns something true; that value, or None."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(every_s)
    return None


#: a subscriber child: argv publish, control, seconds (after its first reading); prints a
#: JSON line per batch (run, channel, first sequence, count, latency of its last reading)
#: and a last line with the client's missed and restarts counts
SUBSCRIBER = """
import json, sys, time
from wavemeter.service import Client
publish, control, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
client = Client(publish, control)
print(json.dumps({"started": True}), flush=True)
end = None
for batch in client.batches(timeout_s=20):
    now = time.time_ns()
    end = end or time.monotonic() + seconds
    columns = batch.columns
    print(json.dumps({"run": batch.run, "channel": batch.channel,
                      "first": int(columns["sequence"][0]), "count": len(batch),
                      "latency_ns": now - int(columns["source_time_ns"][-1])}), flush=True)
    if time.monotonic() > end:
        break
print(json.dumps({"missed": client.missed, "restarts": client.restarts}), flush=True)
client.close()
"""


def sequences(batches: list[dict]) -> dict[tuple[str, int], list[int]]:
    """Every sequence number received, by (run, channel), in the order received."""
    found: dict[tuple[str, int], list[int]] = {}
    for batch in batches:
        key = (batch["run"], batch["channel"])
        found.setdefault(key, []).extend(range(batch["first"], batch["first"] + batch["count"]))
    return found


def subscribed(client, channel=None, timeout_s: float = 10.0):
    """``client.readings(channel)`` once the service counts the subscription."""
    readings = client.readings(channel, timeout_s=timeout_s)
    assert wait_for(lambda: client.status()["subscribers"], 10), "no subscription"
    return readings


def make_meter(tmp_path_factory):
    """The simulated meter, its calibration file, a second good one, and a corrupt one."""
    from wavemeter.service.simulated import simulated_meter

    folder = tmp_path_factory.mktemp("calibrations")
    device, calibration = simulated_meter(7)
    calibration.save(folder / "chip.wmcal.json")
    _, other = simulated_meter(8)
    other.save(folder / "other.wmcal.json")
    text = (folder / "chip.wmcal.json").read_text()
    (folder / "corrupt.wmcal.json").write_text(text[: len(text) // 2])
    return device, folder


def lines_of(device, count: int, rng) -> list[str]:
    from wavemeter.service.simulated import NOISE_W, POWER_W

    frequencies = device.center_hz + rng.uniform(-5e9, 5e9, count)
    powers_mw = device.powers(frequencies, power_w=POWER_W, noise_w=NOISE_W, rng=rng) * 1e3
    return [",".join(repr(float(p)) for p in row) for row in powers_mw]


def feed_lines(port: int, lines: list[str], *, header="P1_mW,P2_mW,P3_mW", pause_s=0.001):
    """Connect to the TCP source and write a header and lines (keeps the connection open
    while writing; returns the socket)."""
    connection = socket.create_connection(("127.0.0.1", port))
    connection.sendall((header + "\n").encode())
    for line in lines:
        connection.sendall((line + "\n").encode())
        time.sleep(pause_s)
    return connection


def tcp_service(meter, *extra):
    device, folder = meter
    return serving(
        [str(folder / "chip.wmcal.json"), "--source", "tcp://127.0.0.1:0", *EPHEMERAL, *extra]
    )


def source_port(service) -> int:
    line = next(line for line in service.lines if "source tcp://" in line)
    return int(line.rsplit(":", 1)[1].strip())


def addresses_of(service) -> dict:
    return {"publish": service.addresses["publish"], "control": service.addresses["control"]}
