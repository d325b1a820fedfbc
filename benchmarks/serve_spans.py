"""Where a reading's time goes in `wavemeter serve`: line written -> subscriber holds it.

The companion of ``benchmarks/serve.py`` (same calibration, lines, TCP line source, 1 kHz
pacing and subscriber children): the service child runs with a few functions wrapped to
stamp ``time.time_ns()`` (one clock for every process of the machine), and each subscriber
stamps when ZeroMQ handed it a message and when it held the decoded batch. Per reading:

- written -> arrived: the writer's ``sendall`` returned -> the service turned the bytes into
  lines (the reading's ``source_time_ns``);
- -> parsed: its row block made (``LineParser.rows``);
- -> read out: the calibration's numbers (the reading's ``time_ns``);
- -> publish starts, -> first / last subscriber sent (``Publisher._deliver``);
- -> bookkeeping done: counts, log, trace and metrics after the sends (``Server._process``);
- per subscriber: publish start -> ZeroMQ receive returned, -> decoded, and the total.

The wrapped functions cost a few microseconds each: the total here is a little above
``serve.py``'s. Run: ``python benchmarks/serve_spans.py [--subscribers 3] [--readings 5000]``.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import serve  # noqa: E402
from _script import Parser, positive_int  # noqa: E402

#: the service child: wrap, serve, save the stamps at exit (argv: spans .npy, serve's args)
SERVICE = """
import atexit, sys, time
import numpy as np
from wavemeter.service import lines, publisher, server

out = sys.argv[1]
parsed, sent, rows = [], [], []

def wrap_rows(rows_of):
    def wrapped(self, lines_, arrival_ns):
        block = rows_of(self, lines_, arrival_ns)
        if block is not None:
            parsed.append(time.time_ns())
        return block
    return wrapped

def wrap_deliver(deliver):
    def wrapped(self, subscriber, topic, body, count=True):
        done = deliver(self, subscriber, topic, body, count)
        if topic.startswith(b"ch/"):
            sent.append(time.time_ns())
        return done
    return wrapped

def wrap_publish(publish):
    def wrapped(self, batch):
        start, began = len(sent), time.time_ns()
        publish(self, batch)
        first, last = (sent[start], sent[-1]) if len(sent) > start else (0, 0)
        rows.append([int(batch.columns["sequence"][0]), len(batch), began, first, last,
                     parsed[-1] if parsed else 0, 0])
    return wrapped

def wrap_process(process):
    def wrapped(self, block):
        start = len(rows)
        process(self, block)
        for row in rows[start:]:
            row[6] = time.time_ns()
    return wrapped

lines.LineParser.rows = wrap_rows(lines.LineParser.rows)
publisher.Publisher._deliver = wrap_deliver(publisher.Publisher._deliver)
publisher.Publisher.publish = wrap_publish(publisher.Publisher.publish)
server.Server._process = wrap_process(server.Server._process)
atexit.register(lambda: np.save(out, np.array(rows, dtype=np.int64).reshape(-1, 7)))
sys.argv = ["wavemeter", *sys.argv[2:]]
from wavemeter.cli.app import main
sys.exit(main())
"""

#: a subscriber child: argv publish, control, first sequence, readings, output .npy path;
#: saves per reading (sequence, source_time_ns, time_ns, received, held) from first on
SUBSCRIBER = """
import sys, time, numpy as np
from wavemeter.service import Client, client as client_module
publish, control, first, count, out = sys.argv[1:6]
first, count = int(first), int(count)
received = [0]
take = client_module._Tracker.take
def stamped(self, frames):
    received[0] = time.time_ns()
    return take(self, frames)
client_module._Tracker.take = stamped
client = Client(publish, control)
batches = client.batches(timeout_s=60)
print("subscribed", flush=True)
kept = []
for batch in batches:
    held = time.time_ns()
    c = batch.columns
    for k in np.flatnonzero(c["sequence"] >= first):
        kept.append((c["sequence"][k], c["source_time_ns"][k], c["time_ns"][k], received[0], held))
    if len(kept) >= count:
        break
np.save(out, np.array(kept[:count], dtype=np.int64))
print(client.missed, flush=True)
client.close()
"""


def quantiles(values_ns: np.ndarray) -> str:
    found = np.percentile(values_ns * 1e-3, [50, 90, 99])
    return " | ".join(f"{value:.1f}" for value in found)


def main(argv=None) -> int:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--readings", type=positive_int, default=5000)
    parser.add_argument("--subscribers", type=positive_int, default=3)
    args = parser.parse_args(argv)
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        calibration, lines = serve.calibration_and_lines(folder, args.readings)
        spans_path = folder / "service-spans.npy"
        service = serve.Service(calibration, launcher=("-c", SERVICE, str(spans_path)))
        try:
            serve.paced(service.write, lines[: serve.WARMUP], 1000.0)
            service.sent = first = serve.WARMUP
            children = serve.subscribers(
                service, args.subscribers, first, len(lines), folder, script=SUBSCRIBER
            )
            serve.wait_subscribed(service, args.subscribers)
            written = serve.paced(service.write, lines, 1000.0)
            kept = []
            for child, out in children:
                assert int(child.communicate(timeout=120)[0].split()[-1]) == 0
                kept.append(np.load(out))
        finally:
            service.close()
        stamps = np.load(spans_path)
    by_sequence = {}
    for sequence, count, *times in stamps:
        for k in range(count):
            by_sequence[int(sequence) + k] = times
    print_table(kept, by_sequence, written, first, args, load)
    return 0


def print_table(kept, by_sequence, written, first, args, load) -> None:
    sequence = kept[0][:, 0]
    began, first_sent, last_sent, parsed, done = np.array([by_sequence[int(s)] for s in sequence]).T
    arrived, read_out = kept[0][:, 1], kept[0][:, 2]
    line = written[sequence - first]
    print(
        f"## serve: where a reading's time goes, 1 kHz, {args.readings} readings, "
        f"{args.subscribers} subscribers (us)\n"
    )
    print("| span | median | p90 | p99 |")
    print("|---|---:|---:|---:|")
    rows = [
        ("line written -> service has it as a line", arrived - line),
        ("-> parsed (row block)", parsed - arrived),
        ("-> read out (calibration)", read_out - parsed),
        ("-> publish starts (numbering, columns)", began - read_out),
        ("-> first subscriber sent (encode, send)", first_sent - began),
        ("-> last subscriber sent", last_sent - began),
        ("bookkeeping after the sends (not on the path)", done - last_sent),
    ]
    for k, readings in enumerate(kept):
        start = np.array([by_sequence[int(s)][0] for s in readings[:, 0]])
        total_line = written[readings[:, 0] - first]
        rows += [
            (f"subscriber {k}: publish starts -> ZeroMQ hands it over", readings[:, 3] - start),
            (f"subscriber {k}: -> decoded, held", readings[:, 4] - readings[:, 3]),
            (f"subscriber {k}: total, line written -> held", readings[:, 4] - total_line),
        ]
    for label, values in rows:
        print(f"| {label} | {quantiles(values)} |")
    print(
        f"\nmachine: {os.cpu_count()} cores, load average {load[0]:.1f} at the start and "
        f"{os.getloadavg()[0]:.1f} at the end"
    )


if __name__ == "__main__":
    sys.exit(main())
