"""The end-to-end run of benchmarks/lock.py: a real ``wavemeter serve --simulate`` process
(two channels at 1 kHz each, a reference on channel 1, the chip warming 0.5 K over 15 s),
locked from a client in this process 1 GHz away, judged on its log."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

__all__ = ["through_service"]

_READY = re.compile(r"publish (?P<publish>[^\s,]+), control (?P<control>[^\s,]+)")


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _true_now(client, timeout_s=30.0) -> float:
    from wavemeter.service import ServiceError

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            latest = client.latest(0)
        except ServiceError:  # no reading of channel 0 yet
            latest = None
        if latest:
            return latest["true_frequency_hz"]
        time.sleep(0.05)
    raise RuntimeError("the service published no reading of channel 0")


def through_service(folder: Path, bandwidth_hz: float, reference_hz: float, seconds=20.0):
    """Run the service, lock channel 0 1 GHz away for ``seconds``; what the log says."""
    from wavemeter.service import Client, read_log

    args = [
        sys.executable,
        "-m",
        "wavemeter",
        "serve",
        "--simulate",
        "--channels",
        "2",
        "--rate",
        "2kHz",
        "--reference",
        f"1={reference_hz / 1e12:.6f}THz",
        "--chip-ramp",
        "0.5K/15s",
        "--log",
        str(folder),
        "--publish",
        "tcp://127.0.0.1:0",
        "--control",
        "tcp://127.0.0.1:0",
        "--http",
        "off",
    ]
    process = subprocess.Popen(args, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    addresses: dict = {}
    lines: list[str] = []

    def read():
        for line in process.stderr:
            lines.append(line)
            found = _READY.search(line)
            if found:
                addresses.update(found.groupdict())

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 60
        while "publish" not in addresses and process.poll() is None:
            if time.monotonic() > deadline:
                raise RuntimeError("the service did not start")
            time.sleep(0.05)
        if "publish" not in addresses:
            raise RuntimeError("the service did not start: " + "".join(lines))
        with Client(addresses["publish"], addresses["control"]) as client:
            setpoint = _true_now(client) + 1e9
            client.lock(0, setpoint, bandwidth_hz=bandwidth_hz)
            cpu_start, wall_start = _cpu_s(process.pid), time.monotonic()
            time.sleep(seconds)
            cpu = (_cpu_s(process.pid) - cpu_start) / (time.monotonic() - wall_start)
            status = client.lock_status(0)
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(30)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        reader.join(5)
    table = read_log(folder, channel=0)
    state = np.nan_to_num(table["lock_state"].to_numpy(zero_copy_only=False))
    first = int(np.flatnonzero(state > 0)[0])
    ns = table["source_time_ns"].to_numpy()[first:]
    times = (ns - ns[0]) * 1e-9
    error = table["true_frequency_hz"].to_numpy()[first:] - setpoint
    events = [json.loads(line) for line in (folder / "reanchors.jsonl").open()]
    return {
        "times_s": times,
        "error_hz": error,
        "status": status,
        "cpu": cpu,
        "accepted": sum(e["accepted"] for e in events),
        "refused": sum(not e["accepted"] for e in events),
    }
