"""A lock output written outside wavemeter, registered through its entry points.

``file_dac`` makes a "DAC" that appends every voltage it is told to output to a text file,
one line ``<channel> <volts>`` each, and ``closed`` when the service stops: what a test can
read back. It implements the documented sink interface and nothing else.
"""

from pathlib import Path


class FileDac:
    """A DAC channel that writes its voltages to a file."""

    def __init__(self, channel: int, path: str, low: float, high: float, start: float):
        self.channel = channel
        self.path = Path(path)
        self.limits_v = (low, high)
        self.output_v = start

    def write(self, voltage_v: float) -> None:
        low, high = self.limits_v
        if not low <= voltage_v <= high:
            raise ValueError(f"{voltage_v} V is outside {low} .. {high} V")
        with self.path.open("a") as handle:
            handle.write(f"{self.channel} {voltage_v!r}\n")
        self.output_v = voltage_v

    def close(self) -> None:
        with self.path.open("a") as handle:
            handle.write("closed\n")


def file_dac(channel, path, low="-10", high="10", start="0"):
    """The entry point: options come from ``--output N=toy_file:path=...,start=...`` as
    strings."""
    return FileDac(channel, path, float(low), float(high), float(start))
