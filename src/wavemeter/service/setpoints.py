"""What a lock holds a laser to: a fixed frequency, or a scan (a ramp or a triangle).

A :class:`Scan` is a setpoint that moves with time: ``center_hz`` plus a periodic offset of
peak ``amplitude_hz`` and period ``period_s``, starting at the centre when the lock engages
and going up. A triangle goes up to ``+amplitude``, down to ``-amplitude`` and back; a ramp
goes up from ``-amplitude`` to ``+amplitude`` and flies back in one step (a step of twice the
amplitude, which the capture range must allow).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..exceptions import InputError

__all__ = ["Scan", "SCAN_SHAPES", "check_setpoint_hz"]

SCAN_SHAPES = ("triangle", "ramp")


def check_setpoint_hz(value, name: str = "setpoint_hz") -> float:
    """A setpoint (Hz): a finite number > 0.

    Raises
    ------
    InputError
        Naming ``name`` otherwise.
    """
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise InputError(f"{name} {value!r}: expected a frequency in Hz, > 0", parameter=name)
    if not math.isfinite(value):
        raise InputError(f"{name} {value!r} is not finite", parameter=name)
    return float(value)


@dataclass(frozen=True)
class Scan:
    """A setpoint that scans.

    Parameters
    ----------
    center_hz : float
        The scan's centre (Hz), > 0.
    amplitude_hz : float
        Its peak offset from the centre (Hz), >= 0.
    period_s : float
        Its period (s), > 0.
    shape : {"triangle", "ramp"}
        A triangle, or a ramp (sawtooth) that flies back at the end of each period.

    Raises
    ------
    InputError
        For a value out of range (the message names it).
    """

    center_hz: float
    amplitude_hz: float
    period_s: float
    shape: str = "triangle"

    def __post_init__(self):
        check_setpoint_hz(self.center_hz, "center_hz")
        for name, minimum in (("amplitude_hz", 0.0), ("period_s", 0.0)):
            value = getattr(self, name)
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not (ok and math.isfinite(value) and value >= minimum):
                raise InputError(f"{name} {value!r}: expected a number >= 0", parameter=name)
        if not self.period_s > 0:
            raise InputError(f"period_s {self.period_s!r}: expected > 0", parameter="period_s")
        if self.shape not in SCAN_SHAPES:
            raise InputError(
                f"shape {self.shape!r}: expected one of {SCAN_SHAPES}", parameter="shape"
            )

    def at(self, elapsed_s: float) -> float:
        """The setpoint (Hz) ``elapsed_s`` seconds after the scan started."""
        phase = (elapsed_s / self.period_s) % 1.0
        if self.shape == "triangle":
            # 0 -> +1 at a quarter, -1 at three quarters, back to 0
            offset = abs(((phase + 0.75) % 1.0) * 4.0 - 2.0) - 1.0
        else:
            offset = 2.0 * ((phase + 0.5) % 1.0) - 1.0
        return self.center_hz + self.amplitude_hz * offset

    def describe(self) -> dict:
        """The scan's settings, JSON-ready."""
        return {
            "center_hz": self.center_hz,
            "amplitude_hz": self.amplitude_hz,
            "period_s": self.period_s,
            "shape": self.shape,
        }
