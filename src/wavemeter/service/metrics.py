"""The service's Prometheus metrics (prometheus_client), per channel where it matters.

Counters and gauges are updated once per batch, never per reading; the text format is made
by ``prometheus_client.generate_latest`` when ``/metrics`` is asked for. Each service has its
own registry (two services in one process do not mix).
"""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest

from ..calibration import ReadingFlag

__all__ = ["Metrics", "LATENCY_BUCKETS_S"]

#: latency histogram buckets (s): 50 us .. 100 ms
LATENCY_BUCKETS_S = (5e-5, 1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2e-2, 5e-2, 0.1)
_BITS = [(flag.name, int(flag)) for flag in ReadingFlag]


class Metrics:
    """The metrics of one service."""

    def __init__(self):
        self.registry = CollectorRegistry()
        r = self.registry
        self.readings = Counter("wavemeter_readings", "Readings published", ["channel"], registry=r)
        self.rate = Gauge(
            "wavemeter_readings_per_second",
            "Readings per second over the last second",
            ["channel"],
            registry=r,
        )
        self.flags = Counter(
            "wavemeter_flagged_readings",
            "Readings with each flag bit set",
            ["channel", "flag"],
            registry=r,
        )
        self.latency = Histogram(
            "wavemeter_latency_seconds",
            "From a block of readings reaching the service to its batch published",
            ["channel"],
            buckets=LATENCY_BUCKETS_S,
            registry=r,
        )
        self.subscribers = Gauge("wavemeter_subscribers", "Connected subscribers", registry=r)
        self.dropped = Counter(
            "wavemeter_dropped_readings",
            "Readings not delivered to a subscriber whose queue was full",
            ["channel"],
            registry=r,
        )
        self.signal = Gauge(
            "wavemeter_channel_signal",
            "1 while the channel has signal, else 0",
            ["channel"],
            registry=r,
        )
        self.frequency = Gauge(
            "wavemeter_frequency_hz", "The channel's latest frequency", ["channel"], registry=r
        )
        self.unroutable = Counter(
            "wavemeter_unroutable_lines", "Source lines without a readable channel", registry=r
        )
        self.logged = Gauge("wavemeter_logged_readings", "Readings written to the log", registry=r)
        self._children: dict[str, tuple] = {}  # per channel: readings, latency, frequency

    def batch(self, channel: str, flags, latency_s: float, frequency_hz: float) -> None:
        """Count a published batch (flags: its int64 flag array)."""
        children = self._children.get(channel)
        if children is None:
            children = self._children[channel] = (
                self.readings.labels(channel),
                self.latency.labels(channel),
                self.frequency.labels(channel),
            )
        readings, latency, frequency = children
        readings.inc(len(flags))
        latency.observe(latency_s)
        if frequency_hz == frequency_hz:
            frequency.set(frequency_hz)
        if flags.any():
            for name, bit in _BITS:
                count = int((flags & bit).astype(bool).sum())
                if count:
                    self.flags.labels(channel, name).inc(count)

    def text(self) -> bytes:
        """The metrics in the Prometheus text format."""
        return generate_latest(self.registry)
