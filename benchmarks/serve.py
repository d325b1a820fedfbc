"""Issue 30's benchmark: `wavemeter serve` against `wavemeter stream`, side by side in one run.

Every case writes lines of port readings (the Table 1 3x3 device, seed 7, calibrated on one
FSR) into a real child process and times each reading from the moment its line was written
(``time.time_ns()`` after ``sendall``/``flush``) to the moment a reader in another process
holds it decoded: for ``stream`` the output line read back from its standard output, for
``serve`` the reading a :class:`wavemeter.service.Client` subscriber got (its batch decoded).
Lines go to ``serve`` over its TCP line source.

- latency at 1 kHz: ``stream``; ``serve`` with 1, 2 and 3 subscribers; ``serve`` with 3
  subscribers one of which is stopped (SIGSTOP) for the whole run. Each case runs
  ``--repeats`` times alternating with the others; the table gives the median over runs of
  each run's median and p99. The stopped subscriber's effect is the p99 of the 2 others
  against the p99 with 2 subscribers and none stopped (the same processes reading; against
  3 readers it would credit the stopped one with the CPU it no longer takes).
- CPU per 1 kHz channel: the child's user + system CPU seconds per second of the 1 kHz run
  with one subscriber (``/proc/PID/stat``), and the same for ``stream``.
- the highest sustained rate with one subscriber and ``--log`` on and no drop: lines sent at
  a set rate for ``--seconds``; a rate passes when the subscriber got every reading in order
  (no gap), the service dropped none, the log holds them all, the last arrived within half a
  second of the last line written (no growing backlog), and the lines were taken at 95 % of
  the rate or more (a service that falls behind slows the writer through TCP). Rates double
  until one fails.

Targets (issue 30): median <= 0.5 ms and p99 <= 2 ms at 1 kHz with 3 subscribers; >= 100,000
readings/s sustained; a stopped subscriber changes the others' p99 by less than 20 %.
Run: ``python benchmarks/serve.py`` (``--quick`` for a short smoke run).
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _script import Parser, positive_int  # noqa: E402

HEADER = "P1_mW,P2_mW,P3_mW"
TARGET_MEDIAN_S = 0.5e-3
TARGET_P99_S = 2e-3
TARGET_RATE = 100_000
TARGET_STOPPED_CHANGE = 0.20
#: lines written before each timed run of a child (its imports, its first readings)
WARMUP = 200
READY = re.compile(
    r"publish (?P<publish>[^\s,]+), control (?P<control>[^\s,]+), source tcp://[^:]+:(?P<port>\d+)"
)

#: a subscriber child: argv publish, control, first sequence, readings, output .npy path;
#: saves (sequence, receive time ns) of each reading from the first sequence on
SUBSCRIBER = """
import sys, time, numpy as np
from wavemeter.service import Client
publish, control, first, count, out = sys.argv[1:6]
first, count = int(first), int(count)
client = Client(publish, control)
batches = client.batches(timeout_s=60)
print("subscribed", flush=True)
sequences, times = [], []
got = 0
for batch in batches:
    now = time.time_ns()
    numbers = batch.columns["sequence"]
    keep = numbers >= first
    sequences.append(numbers[keep]); times.append(np.full(int(keep.sum()), now))
    got += int(keep.sum())
    if got >= count:
        break
np.save(out, np.stack([np.concatenate(sequences)[:count], np.concatenate(times)[:count]]))
print(client.missed, flush=True)
client.close()
"""


def calibration_and_lines(folder: Path, readings: int):
    """A calibration file of the simulated meter and ``readings`` data lines (mW)."""
    from wavemeter.service.simulated import NOISE_W, POWER_W, simulated_meter

    device, calibration = simulated_meter(7)
    path = folder / "chip.wmcal.json"
    calibration.save(path)
    rng = np.random.default_rng(7)
    frequency = device.center_hz + rng.uniform(-10e9, 10e9, readings)
    powers_mw = device.powers(frequency, power_w=POWER_W, noise_w=NOISE_W, rng=rng) * 1e3
    return path, [",".join(repr(float(p)) for p in row) + "\n" for row in powers_mw]


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def paced(write, lines: list[str], rate_hz: float) -> np.ndarray:
    """Write ``lines`` one at a time at ``rate_hz``; the time.time_ns() after each write."""
    written = np.empty(len(lines), dtype=np.int64)
    start = time.perf_counter()
    for index, line in enumerate(lines):
        wait = start + index / rate_hz - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        write(line)
        written[index] = time.time_ns()
    return written


class Service:
    """A `wavemeter serve CAL --source tcp://127.0.0.1:0` child and one writer connection."""

    def __init__(self, calibration: Path, *extra, launcher=("-m", "wavemeter")):
        command = [
            sys.executable,
            *launcher,
            "serve",
            str(calibration),
            "--source",
            "tcp://127.0.0.1:0",
            "--publish",
            "tcp://127.0.0.1:0",
            "--control",
            "tcp://127.0.0.1:0",
            "--http",
            "off",
            *extra,
        ]
        self.process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True)
        line = self.process.stderr.readline()
        match = READY.search(line)
        if match is None:
            self.process.kill()
            raise RuntimeError(f"wavemeter serve did not start: {line}{self.process.stderr.read()}")
        self.publish, self.control = match["publish"], match["control"]
        threading.Thread(target=self.process.stderr.read, daemon=True).start()
        self.writer = socket.create_connection(("127.0.0.1", int(match["port"])))
        self.writer.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.writer.sendall((HEADER + "\n").encode())
        self.sent = 0  # data lines written so far: the next one's sequence number

    def write(self, line: str) -> None:
        self.writer.sendall(line.encode())

    def status(self) -> dict:
        from wavemeter.service import Client

        with Client(self.publish, self.control) as client:
            return client.status()

    def close(self) -> None:
        self.writer.close()
        self.process.send_signal(signal.SIGTERM)
        try:
            self.process.wait(60)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


def subscribers(
    service: Service, count: int, first: int, readings: int, folder: Path, script=SUBSCRIBER
):
    """Start ``count`` subscriber children that keep readings ``first`` .. on."""
    children = []
    for k in range(count):
        out = folder / f"subscriber-{first}-{k}.npy"
        child = subprocess.Popen(
            [
                sys.executable,
                "-c",
                script,
                service.publish,
                service.control,
                str(first),
                str(readings),
                str(out),
            ],
            stdout=subprocess.PIPE,
            text=True,
        )
        assert child.stdout.readline().strip() == "subscribed"
        children.append((child, out))
    return children


def wait_subscribed(service: Service, count: int) -> None:
    deadline = time.monotonic() + 30
    while len(service.status()["subscribers"]) != count:
        if time.monotonic() > deadline:
            raise RuntimeError(f"{count} subscribers did not join")
        time.sleep(0.05)


def serve_latency(service, lines, folder, count: int, stopped: bool, rate_hz: float):
    """Latencies (s) of one subscriber (the first) over one run, and the CPU per second."""
    first = service.sent
    children = subscribers(service, count, first, len(lines), folder)
    if stopped:
        extra = subprocess.Popen(
            [
                sys.executable,
                "-c",
                SUBSCRIBER,
                service.publish,
                service.control,
                "0",
                str(10**9),
                str(folder / "x.npy"),
            ],
            stdout=subprocess.PIPE,
            text=True,
        )
        assert extra.stdout.readline().strip() == "subscribed"
        wait_subscribed(service, count + 1)
        extra.send_signal(signal.SIGSTOP)
    else:
        wait_subscribed(service, count)
    cpu = cpu_s(service.process.pid)
    written = paced(service.write, lines, rate_hz)
    cpu_per_s = (cpu_s(service.process.pid) - cpu) / (len(lines) / rate_hz)
    service.sent += len(lines)
    latencies = []
    for child, out in children:
        missed = int(child.communicate(timeout=120)[0].split()[-1])
        sequences, received = np.load(out)
        assert missed == 0 and (sequences == np.arange(first, first + len(lines))).all()
        latencies.append((received - written) * 1e-9)
    if stopped:
        extra.kill()
        extra.wait()
        extra.stdout.close()
    wait_subscribed(service, 0)
    return np.concatenate(latencies), cpu_per_s


def stream_latency(calibration: Path, lines: list[str], rate_hz: float):
    """Latencies (s) of `wavemeter stream` at ``rate_hz`` and its CPU per second."""
    child = subprocess.Popen(
        [sys.executable, "-m", "wavemeter", "stream", str(calibration), "--quiet"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
    )
    child.stdin.write(f"{HEADER}\n".encode())
    child.stdin.flush()
    child.stdout.readline()
    for line in lines[:WARMUP]:  # imports and first readings, as the service's warm-up
        child.stdin.write(line.encode())
        child.stdin.flush()
        child.stdout.readline()
    received = np.empty(len(lines), dtype=np.int64)

    def read():
        for index in range(len(lines)):
            child.stdout.readline()
            received[index] = time.time_ns()

    reader = threading.Thread(target=read)
    reader.start()

    def write(line):
        child.stdin.write(line.encode())
        child.stdin.flush()

    cpu = cpu_s(child.pid)
    written = paced(write, lines, rate_hz)
    reader.join()
    cpu_per_s = (cpu_s(child.pid) - cpu) / (len(lines) / rate_hz)
    child.stdin.close()
    child.wait(60)
    child.stdout.close()
    return (received - written) * 1e-9, cpu_per_s


def sustained(calibration: Path, lines: list[str], rate: int, seconds: float, folder: Path):
    """Whether ``rate`` readings/s for ``seconds`` reach one subscriber and the log whole."""
    log = folder / f"log-{rate}"
    service = Service(calibration, "--log", str(log))
    try:
        total = int(rate * seconds)
        children = subscribers(service, 1, 0, total, folder)
        wait_subscribed(service, 1)
        chunk_s = 0.01
        per_chunk = max(1, int(rate * chunk_s))
        text = "".join(lines)
        block = (text * (per_chunk // len(lines) + 1)).splitlines(keepends=True)[:per_chunk]
        data = "".join(block).encode()
        start = time.perf_counter()
        first_written = time.time_ns()
        for k in range(total // per_chunk):
            wait = start + k * chunk_s - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            service.writer.sendall(data)
        last_written = time.time_ns()
        child, out = children[0]
        try:
            missed = int(child.communicate(timeout=seconds * 20 + 30)[0].split()[-1])
        except subprocess.TimeoutExpired:
            child.kill()
            return False, "the subscriber did not get every reading in time"
        sequences, received = np.load(out)
        sent = (total // per_chunk) * per_chunk
        status = service.status()
    finally:
        service.close()
    from wavemeter.service import read_log

    logged = read_log(log).num_rows
    lag_s = (received.max() - last_written) * 1e-9
    # a service that falls behind slows the writer (TCP): the writing must have kept its pace
    writing_s = (last_written - first_written) * 1e-9 + chunk_s
    achieved = sent / writing_s
    whole = missed == 0 and len(sequences) == sent and (np.diff(sequences) == 1).all()
    kept_up = lag_s <= 0.5 and achieved >= 0.95 * rate
    ok = whole and status["dropped_messages"] == 0 and logged == sent and kept_up
    detail = (
        f"{sent} sent, gaps {missed}, dropped {status['dropped_messages']}, logged {logged}, "
        f"last {lag_s * 1e3:.0f} ms after the last line, lines taken at {achieved:,.0f}/s"
    )
    return ok, detail


def summary(runs: list[np.ndarray]) -> tuple[float, float]:
    """Median over runs of each run's median and p99 (s)."""
    return (
        float(np.median([np.median(r) for r in runs])),
        float(np.median([np.percentile(r, 99) for r in runs])),
    )


def main(argv=None) -> int:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--readings",
        type=positive_int,
        default=5000,
        help="readings per latency run at 1 kHz (default 5000)",
    )
    parser.add_argument("--repeats", type=positive_int, default=3, help="runs per case")
    parser.add_argument(
        "--seconds", type=float, default=3.0, help="seconds of each sustained-rate run"
    )
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    args = parser.parse_args(argv)
    load = os.getloadavg()
    readings, repeats, seconds = args.readings, args.repeats, args.seconds
    rates = [12_500, 25_000, 50_000, 100_000, 200_000, 400_000]
    if args.quick:
        readings, repeats, seconds, rates = 300, 1, 0.5, [2_000]
    rate_hz = 1000.0
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        calibration, lines = calibration_and_lines(folder, readings)
        runs = {key: [] for key in ("stream", "serve1", "serve2", "serve3", "serve3stopped")}
        cpu = {"stream": [], "serve1": []}
        service = Service(calibration)
        try:
            paced(service.write, lines[:WARMUP], rate_hz)  # imports, first readings
            service.sent += WARMUP
            for _ in range(repeats):
                latency, cpu_s_ = stream_latency(calibration, lines, rate_hz)
                runs["stream"].append(latency)
                cpu["stream"].append(cpu_s_)
                for key, count, stopped in (
                    ("serve1", 1, False),
                    ("serve2", 2, False),
                    ("serve3", 3, False),
                    ("serve3stopped", 2, True),
                ):
                    latency, cpu_s_ = serve_latency(service, lines, folder, count, stopped, rate_hz)
                    runs[key].append(latency)
                    if key == "serve1":
                        cpu["serve1"].append(cpu_s_)
        finally:
            service.close()
        rate_results = []
        for rate in rates:
            ok, detail = sustained(calibration, lines, rate, seconds, folder)
            rate_results.append((rate, ok, detail))
            if not ok:
                break
    print_table(runs, cpu, rate_results, readings, repeats, seconds, load)
    return 0


def print_table(runs, cpu, rate_results, readings, repeats, seconds, load) -> None:
    def verdict(passed: bool) -> str:
        return "PASS" if passed else "FAIL"

    rows = []
    labels = {
        "stream": "wavemeter stream (stdout)",
        "serve1": "serve, 1 subscriber",
        "serve2": "serve, 2 subscribers",
        "serve3": "serve, 3 subscribers",
        "serve3stopped": "serve, 3 subscribers, 1 stopped (the 2 others)",
    }
    medians = {key: summary(value) for key, value in runs.items()}
    for key, (median, p99) in medians.items():
        target, result = "", ""
        if key == "serve3":
            target = "median <= 0.5 ms, p99 <= 2 ms"
            result = verdict(median <= TARGET_MEDIAN_S and p99 <= TARGET_P99_S)
        rows.append((labels[key], f"{median * 1e3:.3f}", f"{p99 * 1e3:.3f}", target, result))
    change = medians["serve3stopped"][1] / medians["serve2"][1] - 1
    print(
        f"## wavemeter serve vs stream: latency line written -> reader holds the reading, "
        f"1 kHz, {readings} readings x {repeats} runs (median over runs)\n"
    )
    print("| case | median (ms) | p99 (ms) | target | result |")
    print("|---|---:|---:|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print(
        f"| stopped subscriber: the others' p99 vs 2 subscribers | | {change * 100:+.1f} % "
        "| < 20 % | "
        f"{verdict(abs(change) < TARGET_STOPPED_CHANGE)} |"
    )
    print("\n## CPU per 1 kHz channel (CPU seconds per second, median over runs)\n")
    print("| process | CPU |")
    print("|---|---:|")
    print(f"| wavemeter stream | {np.median(cpu['stream']):.3f} |")
    print(f"| wavemeter serve (1 subscriber) | {np.median(cpu['serve1']):.3f} |")
    print(
        f"\n## highest sustained rate, 1 subscriber, --log on, no drop ({seconds:g} s per rate)\n"
    )
    print("| readings/s | result | detail |")
    print("|---:|---|---|")
    for rate, ok, detail in rate_results:
        print(f"| {rate:,} | {'whole' if ok else 'lost or late'} | {detail} |")
    best = max((rate for rate, ok, _ in rate_results if ok), default=0)
    print(
        f"\nhighest sustained: {best:,} readings/s; target >= {TARGET_RATE:,}: "
        f"{verdict(best >= TARGET_RATE)}"
    )
    print(
        f"machine: {os.cpu_count()} cores, load average {load[0]:.1f} at the start and "
        f"{os.getloadavg()[0]:.1f} at the end (other processes share the cores)"
    )


if __name__ == "__main__":
    sys.exit(main())
