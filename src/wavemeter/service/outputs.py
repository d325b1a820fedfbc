"""Where a lock's output goes: a sink (a DAC channel, the simulated actuator), and plug-ins.

A sink is any object with

- ``limits_v``: ``(low, high)``, the voltages it can output;
- ``output_v``: the voltage it outputs now (a lock starts from there, so engaging never
  jumps);
- ``write(voltage_v)``: output a voltage (called on the service's loop once per batch of
  readings the output changed on; it must return quickly, and raise to report a failure);
- optionally ``close()``, called when the service stops, and ``tuning_hz_per_v`` /
  ``response_s`` when it knows the laser's tuning (the simulated actuator does), which a
  lock then uses to set its gains from a bandwidth.

Sinks of other packages are found through the entry-point group :data:`ENTRY_POINT_GROUP`
(``wavemeter.outputs``): an entry point names a factory called as ``factory(channel=N,
**options)`` with the options of ``--output N=NAME:KEY=VALUE,...`` as strings, returning a
sink. The user guide's page on locks has a worked example for a DAC.
"""

from __future__ import annotations

import math
from typing import Protocol

from ..exceptions import InputError

__all__ = [
    "OutputSink",
    "ENTRY_POINT_GROUP",
    "output_names",
    "load_output",
    "parse_output",
    "check_sink",
]

ENTRY_POINT_GROUP = "wavemeter.outputs"


class OutputSink(Protocol):
    """What a lock writes its output to (see the module's description)."""

    limits_v: tuple[float, float]
    output_v: float

    def write(self, voltage_v: float) -> None:
        """Output ``voltage_v`` (V), within ``limits_v``."""


def _entry_points():
    from importlib.metadata import entry_points

    return entry_points(group=ENTRY_POINT_GROUP)


def output_names() -> list[str]:
    """The names of the output plug-ins installed."""
    return sorted(point.name for point in _entry_points())


def parse_output(text: str) -> tuple[int, str, dict[str, str]]:
    """``N=NAME[:KEY=VALUE,...]`` as ``(channel, name, options)``.

    Raises
    ------
    InputError
        For text of another shape (the message gives an example).
    """
    example = "e.g. 0=mydac:device=/dev/ttyUSB0,channel=1"
    number, equals, rest = str(text).partition("=")
    name, _, options_text = rest.partition(":")
    if not equals or not number.strip().isdigit() or not name.strip():
        raise InputError(f"output {text!r}: expected N=NAME[:KEY=VALUE,...], {example}")
    options = {}
    for pair in filter(None, (p.strip() for p in options_text.split(","))):
        key, sign, value = pair.partition("=")
        if not sign or not key.strip():
            raise InputError(f"output {text!r}: option {pair!r} is not KEY=VALUE, {example}")
        options[key.strip()] = value.strip()
    return int(number), name.strip(), options


def load_output(name: str, channel: int, options: dict[str, str]):
    """The sink the plug-in ``name`` makes for ``channel``.

    Raises
    ------
    InputError
        When no plug-in has that name, or its factory refuses the options (its message is
        kept), or what it returns is not a sink.
    """
    points = [point for point in _entry_points() if point.name == name]
    if not points:
        known = ", ".join(output_names()) or "none installed"
        raise InputError(
            f"no output plug-in {name!r} (entry-point group {ENTRY_POINT_GROUP}); installed: "
            f"{known}",
            parameter="output",
        )
    factory = points[0].load()
    try:
        sink = factory(channel=channel, **options)
    except (TypeError, ValueError) as exc:
        raise InputError(f"output plug-in {name!r} for channel {channel}: {exc}") from None
    return check_sink(sink, f"output plug-in {name!r}")


def check_sink(sink, what: str = "the output"):
    """``sink`` if it has what a sink needs, with finite limits and output.

    Raises
    ------
    InputError
        Naming what is missing or wrong.
    """
    missing = [name for name in ("limits_v", "output_v", "write") if not hasattr(sink, name)]
    if missing:
        raise InputError(f"{what} gives a sink without {', '.join(missing)}")
    try:
        low, high = (float(v) for v in sink.limits_v)
        output = float(sink.output_v)
    except (TypeError, ValueError):
        raise InputError(f"{what}: limits_v must be (low, high) and output_v a number") from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high and math.isfinite(output)):
        raise InputError(
            f"{what}: limits_v {sink.limits_v!r} and output_v {sink.output_v!r} must be finite "
            "with low < high"
        )
    return sink
