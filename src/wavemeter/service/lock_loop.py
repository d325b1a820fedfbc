"""A lock's loop: a PI(D) controller in physical units, one reading at a time.

:class:`LockLoop` turns readings of one laser (time, frequency, flags) into an output
voltage: ``u = I - kp e - kd dm/dt`` with ``I -= ki e dt`` and ``e = reading - setpoint``
(the mean over ``average`` readings), clamped to the output limits with conditional
integration (the integrator stops while the output sits at a limit and the error would push
it further: no wind-up). It is pure: no sockets, no clock (the times come with the readings),
so the service calls :meth:`LockLoop.step` for every reading and a benchmark runs a minute
at 1 kHz in a second. Its safety rules, each counted:

- a reading flagged INVALID, OFF_MODEL, OUTSIDE_SPAN or ORDER_AMBIGUOUS (or NaN) never moves
  the output: the loop holds and counts it;
- an error beyond the capture range unlocks (the output stays where it is) and raises an alarm;
- an output at a limit for ``rail_s`` raises the railing alarm;
- a hold (no signal, the owner silent, a failed output) freezes the output until released;
- engaging and changing settings are bumpless: the integrator starts at the present output.

:meth:`LockSettings.from_bandwidth` sets the gains from the actuator's tuning (Hz/V), its
response time and a loop bandwidth (``docs/user-guide/locks.rst`` derives them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..calibration import ReadingFlag
from ..exceptions import InputError
from .setpoints import Scan, check_setpoint_hz

__all__ = [
    "LockSettings",
    "LockLoop",
    "LOCKED",
    "UNLOCKED",
    "HOLDING",
    "STATE_CODES",
    "HOLD_FLAGS",
    "CAPTURE",
    "RAILING",
    "NO_SIGNAL",
    "OWNER_SILENT",
    "OUTPUT_FAILED",
    "MAX_LOOP_GAIN",
]

LOCKED = "locked"
UNLOCKED = "unlocked"
HOLDING = "holding"
#: the state as the number published in the ``lock_state`` field
STATE_CODES = {UNLOCKED: 0.0, LOCKED: 1.0, HOLDING: 2.0}
#: readings with any of these flags never move the output
HOLD_FLAGS = int(
    ReadingFlag.INVALID
    | ReadingFlag.OFF_MODEL
    | ReadingFlag.OUTSIDE_SPAN
    | ReadingFlag.ORDER_AMBIGUOUS
)
# alarm names
CAPTURE = "capture range"
RAILING = "railing"
NO_SIGNAL = "no signal"
OWNER_SILENT = "owner silent"
OUTPUT_FAILED = "output failed"
#: the largest loop gain per update, ``2 pi B T_update + K kp``, a bandwidth may ask for
#: (above, the loop's one-update delay makes it ring, and at 1 it oscillates)
MAX_LOOP_GAIN = 0.5
#: time constant of the smoothed error (s)
_MEAN_S = 1.0
#: a gap between readings longer than this many reading intervals is a pause, not an interval
_GAP_INTERVALS = 5.0


def _number(name: str, value, *, minimum=None, positive=False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"{name} {value!r}: expected a finite number", parameter=name)
    if positive and not value > 0:
        raise InputError(f"{name} {value!r}: expected a number > 0", parameter=name)
    if minimum is not None and value < minimum:
        raise InputError(f"{name} {value!r}: expected a number >= {minimum}", parameter=name)
    return float(value)


@dataclass(frozen=True)
class LockSettings:
    """What a lock does: its setpoint, gains, limits and safety settings.

    Parameters
    ----------
    setpoint : float or Scan
        The frequency to hold (Hz), or a scan.
    kp_v_per_hz, ki_v_per_hz_s, kd_v_s_per_hz : float
        Proportional (V/Hz), integral (V/(Hz s)) and derivative (V s/Hz) gains; the output
        moves by ``-kp e``, ``-ki e dt``, ``-kd dm/dt`` for an error ``e`` (Hz): positive
        gains for an actuator that tunes up with voltage.
    output_limits_v : (float, float)
        The output's range (V).
    capture_range_hz : float
        An error beyond it unlocks (Hz), > 0.
    average : int
        Readings averaged per update of the controller, >= 1.
    rail_s : float
        Seconds at a limit before the railing alarm, >= 0.
    bandwidth_hz : float, optional
        The loop bandwidth the gains were set from (recorded for status).
    """

    setpoint: float | Scan
    kp_v_per_hz: float
    ki_v_per_hz_s: float
    kd_v_s_per_hz: float = 0.0
    output_limits_v: tuple[float, float] = (-10.0, 10.0)
    capture_range_hz: float = 3e9
    average: int = 1
    rail_s: float = 1.0
    bandwidth_hz: float | None = None

    def __post_init__(self):
        if not isinstance(self.setpoint, Scan):
            object.__setattr__(self, "setpoint", check_setpoint_hz(self.setpoint))
        for name in ("kp_v_per_hz", "ki_v_per_hz_s", "kd_v_s_per_hz"):
            object.__setattr__(self, name, _number(name, getattr(self, name)))
        if self.kp_v_per_hz == 0 and self.ki_v_per_hz_s == 0:
            raise InputError(
                "kp_v_per_hz and ki_v_per_hz_s are both 0: a lock needs a gain",
                parameter="ki_v_per_hz_s",
            )
        try:
            low, high = (float(v) for v in self.output_limits_v)
        except (TypeError, ValueError):
            low = high = math.nan
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise InputError(
                f"output_limits_v {self.output_limits_v!r}: expected (low, high) in V with "
                "low < high",
                parameter="output_limits_v",
            )
        object.__setattr__(self, "output_limits_v", (low, high))
        _number("capture_range_hz", self.capture_range_hz, positive=True)
        if isinstance(self.average, bool) or not isinstance(self.average, int) or self.average < 1:
            raise InputError(
                f"average {self.average!r}: expected a whole number of readings >= 1",
                parameter="average",
            )
        _number("rail_s", self.rail_s, minimum=0.0)

    @classmethod
    def from_bandwidth(
        cls,
        setpoint,
        *,
        actuator_hz_per_v: float,
        bandwidth_hz: float,
        response_s: float = 0.0,
        **settings,
    ) -> LockSettings:
        """Settings with the gains of a loop of bandwidth ``bandwidth_hz`` (Hz).

        The laser is tuned by ``actuator_hz_per_v`` (Hz/V) through a first-order response
        of time constant ``response_s`` (s). The PI zero cancels that pole: ``ki = 2 pi B /
        K`` and ``kp = ki response_s``, so the open loop is ``2 pi B / s`` and crosses unity
        at ``B``.

        Raises
        ------
        InputError
            For a tuning of 0, a bandwidth <= 0, a negative response time.
        """
        actuator = _number("actuator_hz_per_v", actuator_hz_per_v)
        if actuator == 0:
            raise InputError("actuator_hz_per_v must not be 0", parameter="actuator_hz_per_v")
        bandwidth = _number("bandwidth_hz", bandwidth_hz, positive=True)
        response = _number("response_s", response_s, minimum=0.0)
        ki = 2.0 * math.pi * bandwidth / actuator
        return cls(
            setpoint,
            kp_v_per_hz=ki * response,
            ki_v_per_hz_s=ki,
            bandwidth_hz=bandwidth,
            **settings,
        )

    def check_interval(self, interval_s: float, actuator_hz_per_v: float) -> None:
        """Refuse gains too high for readings every ``interval_s`` (s) on an actuator of
        ``actuator_hz_per_v`` (Hz/V).

        Raises
        ------
        InputError
            When the loop gain per update exceeds :data:`MAX_LOOP_GAIN` (the message names
            the largest bandwidth these readings allow).
        """
        update_s = interval_s * self.average
        gain = abs(actuator_hz_per_v) * (self.ki_v_per_hz_s * update_s + abs(self.kp_v_per_hz))
        if gain > MAX_LOOP_GAIN:
            largest = MAX_LOOP_GAIN / (2.0 * math.pi * update_s)
            raise InputError(
                f"these gains move the laser by {gain:.2g} of its error per update (readings "
                f"every {interval_s * 1e3:.3g} ms, {self.average} per update); at most "
                f"{MAX_LOOP_GAIN} is stable: use a bandwidth below {largest:.3g} Hz",
                parameter="bandwidth_hz",
            )

    def setpoint_at(self, elapsed_s: float) -> float:
        """The setpoint (Hz) ``elapsed_s`` after the lock engaged."""
        if isinstance(self.setpoint, Scan):
            return self.setpoint.at(elapsed_s)
        return self.setpoint

    def describe(self) -> dict:
        """The settings, JSON-ready."""
        scan = isinstance(self.setpoint, Scan)
        return {
            "setpoint_hz": None if scan else self.setpoint,
            "scan": self.setpoint.describe() if scan else None,
            "kp_v_per_hz": self.kp_v_per_hz,
            "ki_v_per_hz_s": self.ki_v_per_hz_s,
            "kd_v_s_per_hz": self.kd_v_s_per_hz,
            "bandwidth_hz": self.bandwidth_hz,
            "output_limits_v": list(self.output_limits_v),
            "capture_range_hz": self.capture_range_hz,
            "average": self.average,
            "rail_s": self.rail_s,
        }

    def with_setpoint(self, setpoint) -> LockSettings:
        """These settings with another setpoint."""
        return replace(self, setpoint=setpoint)


class LockLoop:
    """One laser's lock: readings in, an output voltage out.

    Parameters
    ----------
    settings : LockSettings
        What to do once engaged.
    output_v : float
        The output now (V): where the integrator starts when the loop engages.
    interval_s : float, optional
        The time between readings (s), when known; else learnt from the readings' times.

    Attributes
    ----------
    state : str
        ``"unlocked"``, ``"locked"`` or ``"holding"``.
    output_v : float
        The output (V).
    error_hz : float
        The latest acted-on reading's error, reading - setpoint (Hz); NaN before one.
    reading_error_hz : float
        The latest reading's error (Hz), NaN when it was held or the loop is not engaged.
    error_mean_hz : float
        The errors smoothed over about a second (Hz).
    held : int
        Readings not acted on while engaged (flagged, or during a hold).
    updates : int
        Updates of the output.
    alarms : dict of str to str
        The alarms raised now, name -> message.
    alarm_counts : dict of str to int
        How often each alarm was raised.
    """

    def __init__(self, settings: LockSettings, output_v: float = 0.0, *, interval_s=None):
        self.settings = settings
        low, high = settings.output_limits_v
        self.output_v = min(max(float(output_v), low), high)
        self.state = UNLOCKED
        self.engaged = False
        self.error_hz = math.nan
        self.reading_error_hz = math.nan
        self.error_mean_hz = math.nan
        self.setpoint_hz = math.nan
        self.held = 0
        self.updates = 0
        self.alarms: dict[str, str] = {}
        self.alarm_counts: dict[str, int] = {}
        self.holds: set[str] = set()
        self.interval_s = interval_s
        self._integral_v = self.output_v
        self._sum_hz = 0.0
        self._summed = 0
        self._last_time = None
        self._start_s = None
        self._rail_since = None
        self._last_mean_hz = None

    # ------------------------------------------------------------------ control
    def engage(self, settings: LockSettings | None = None) -> None:
        """Lock (or take new settings while locked), bumplessly: the integrator starts at
        the present output. Clears the capture-range and owner alarms."""
        if settings is not None:
            moved = self.settings.setpoint != settings.setpoint
            self.settings = settings
            low, high = settings.output_limits_v
            self.output_v = min(max(self.output_v, low), high)
            if moved:
                self._start_s = None
        if not self.engaged:
            self._start_s = None
            self._last_mean_hz = None
        self._integral_v = self.output_v
        self._sum_hz, self._summed = 0.0, 0
        self._rail_since = None
        self.engaged = True
        self.release(OWNER_SILENT)
        self.clear(CAPTURE)
        self._refresh(True)

    def disengage(self) -> None:
        """Unlock: the output stays where it is."""
        self.engaged = False
        self.state = UNLOCKED
        self.clear(RAILING)
        self._rail_since = None

    def hold(self, reason: str, message: str) -> None:
        """Freeze the output until :meth:`release` (``reason``: an alarm name)."""
        self.holds.add(reason)
        self.raise_alarm(reason, message)
        self._refresh(False)

    def release(self, reason: str) -> None:
        """End a hold (its alarm too)."""
        if reason in self.holds:
            self.holds.discard(reason)
            self.clear(reason)
            self._refresh(True)

    def raise_alarm(self, name: str, message: str) -> None:
        if name not in self.alarms:
            self.alarm_counts[name] = self.alarm_counts.get(name, 0) + 1
        self.alarms[name] = message

    def clear(self, name: str) -> None:
        self.alarms.pop(name, None)

    def _refresh(self, acted: bool) -> None:
        if not self.engaged:
            self.state = UNLOCKED
        elif self.holds or not acted:
            self.state = HOLDING
        else:
            self.state = LOCKED

    # ------------------------------------------------------------------ readings
    def step(self, time_s: float, frequency_hz: float, flags: int = 0) -> float:
        """Take one reading; return the output (V) after it.

        Parameters
        ----------
        time_s : float
            When it was taken (s, any origin, increasing).
        frequency_hz : float
            The meter's reading (Hz).
        flags : int
            Its :class:`~wavemeter.ReadingFlag` bits.
        """
        last = self._last_time
        if last is not None:
            gap = time_s - last
            if gap > 0:
                interval = self.interval_s
                if interval is None:
                    self.interval_s = gap
                elif gap < _GAP_INTERVALS * interval:
                    self.interval_s = interval + 0.02 * (gap - interval)
        self._last_time = time_s
        if not self.engaged:
            self.reading_error_hz = math.nan
            return self.output_v
        settings = self.settings
        if self._start_s is None:
            self._start_s = time_s
        setpoint = settings.setpoint_at(time_s - self._start_s)
        self.setpoint_hz = setpoint
        if flags & HOLD_FLAGS or frequency_hz != frequency_hz:
            self.held += 1
            self.reading_error_hz = math.nan
            if self.state == LOCKED:
                self.state = HOLDING
            return self.output_v
        error = frequency_hz - setpoint
        if abs(error) > settings.capture_range_hz:
            self.reading_error_hz = error
            self.disengage()
            self.raise_alarm(
                CAPTURE,
                f"error {error / 1e6:.6g} MHz beyond the capture range of "
                f"{settings.capture_range_hz / 1e6:.6g} MHz: unlocked, output kept at "
                f"{self.output_v:.6g} V",
            )
            return self.output_v
        if self.holds:
            self.held += 1
            self.reading_error_hz = error
            return self.output_v
        self.reading_error_hz = error
        self.state = LOCKED
        self._sum_hz += error
        self._summed += 1
        if self._summed < settings.average:
            return self.output_v
        mean = self._sum_hz / self._summed
        self._sum_hz, self._summed = 0.0, 0
        self._update(time_s, mean, setpoint)
        return self.output_v

    def _update(self, time_s: float, error: float, setpoint: float) -> None:
        settings = self.settings
        interval = self.interval_s
        step_s = 0.0 if interval is None else interval * settings.average
        integral = self._integral_v
        change = settings.ki_v_per_hz_s * error * step_s
        derivative = 0.0
        measured = error + setpoint
        if settings.kd_v_s_per_hz and self._last_mean_hz is not None and step_s > 0:
            derivative = settings.kd_v_s_per_hz * (measured - self._last_mean_hz) / step_s
        self._last_mean_hz = measured
        proportional = settings.kp_v_per_hz * error + derivative
        low, high = settings.output_limits_v
        wanted = integral - change - proportional
        if wanted > high and change < 0:  # the integrator runs up to the limit, no further
            integral = max(integral, high + proportional)
            wanted = integral - proportional
        elif wanted < low and change > 0:
            integral = min(integral, low + proportional)
            wanted = integral - proportional
        else:
            integral -= change
        self._integral_v = integral
        self.output_v = min(max(wanted, low), high)
        self.error_hz = error
        mean = self.error_mean_hz
        weight = min(1.0, step_s / _MEAN_S) if step_s > 0 else 1.0
        self.error_mean_hz = error if mean != mean else mean + weight * (error - mean)
        self.updates += 1
        if wanted >= high or wanted <= low:
            if self._rail_since is None:
                self._rail_since = time_s
            if time_s - self._rail_since >= settings.rail_s and RAILING not in self.alarms:
                self.raise_alarm(
                    RAILING,
                    f"the output has sat at its limit {self.output_v:.6g} V for "
                    f"{time_s - self._rail_since:.3g} s",
                )
        else:
            self._rail_since = None
            self.clear(RAILING)
