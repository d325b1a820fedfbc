"""The control requests of locks and of the reference: ``lock``, ``unlock``,
``lock_status``, ``lock_keepalive`` and ``reference_status``.

``lock`` takes the setpoint (``setpoint_hz``, or ``scan``: ``{"center_hz", "amplitude_hz",
"period_s", "shape"}``), the gains (``bandwidth_hz`` with the actuator's tuning
``actuator_hz_per_v`` and ``response_s``, both known to some sinks; or ``kp_v_per_hz``,
``ki_v_per_hz_s``, ``kd_v_s_per_hz``) and the safety settings, checks every one before it
changes anything, and answers with the lock's status (:meth:`ChannelLock.describe
<wavemeter.service.locks.ChannelLock.describe>`).
"""

from __future__ import annotations

import math

from ..exceptions import InputError
from .lock_loop import LockSettings
from .locks import DEFAULT_OWNER_TIMEOUT_S
from .setpoints import Scan

__all__ = ["register_lock_requests", "settings_from_request", "DEFAULT_BANDWIDTH_HZ"]

#: the loop bandwidth of a lock request that names no gains (Hz)
DEFAULT_BANDWIDTH_HZ = 1.0
_GAINS = ("kp_v_per_hz", "ki_v_per_hz_s", "kd_v_s_per_hz")


def settings_from_request(sink, arguments: dict) -> tuple[LockSettings, float | None]:
    """The settings of a lock request on a channel with output ``sink``, and the actuator's
    tuning (Hz/V) where known.

    Raises
    ------
    InputError
        For a setpoint, gain or limit that is missing, of the wrong type or out of range.
    """
    setpoint = arguments.pop("setpoint_hz", None)
    scan = arguments.pop("scan", None)
    if (setpoint is None) == (scan is None):
        raise InputError("give a setpoint_hz or a scan (one of them)", parameter="setpoint_hz")
    if scan is not None:
        if not isinstance(scan, dict):
            raise InputError(
                "scan must be an object with center_hz, amplitude_hz, period_s and shape",
                parameter="scan",
            )
        try:
            setpoint = Scan(**scan)
        except TypeError as exc:
            raise InputError(f"scan: {exc}", parameter="scan") from None
    limits = arguments.pop("output_limits_v", None)
    low, high = (float(v) for v in sink.limits_v)
    if limits is None:
        limits = (low, high)
    elif not (isinstance(limits, list | tuple) and len(limits) == 2):
        raise InputError(
            f"output_limits_v {limits!r}: expected [low, high] in V", parameter="output_limits_v"
        )
    elif not all(isinstance(v, int | float) and low <= v <= high for v in limits):
        raise InputError(
            f"output_limits_v {list(limits)!r}: the output can give {low:g} to {high:g} V",
            parameter="output_limits_v",
        )
    actuator = arguments.pop("actuator_hz_per_v", None)
    if actuator is None:
        actuator = getattr(sink, "tuning_hz_per_v", None)
    response = arguments.pop("response_s", None)
    if response is None:
        response = getattr(sink, "response_s", 0.0)
    bandwidth = arguments.pop("bandwidth_hz", None)
    gains = {name: arguments.pop(name) for name in _GAINS if name in arguments}
    settings = {"output_limits_v": tuple(limits), **arguments}
    if gains and bandwidth is not None:
        raise InputError(
            "give a bandwidth_hz or explicit gains, not both", parameter="bandwidth_hz"
        )
    if gains:
        gains.setdefault("kp_v_per_hz", 0.0)
        gains.setdefault("ki_v_per_hz_s", 0.0)
        return LockSettings(setpoint, **gains, **settings), actuator
    if actuator is None:
        raise InputError(
            "this output does not know the laser's tuning: give actuator_hz_per_v (Hz/V) "
            "with the bandwidth, or explicit gains",
            parameter="actuator_hz_per_v",
        )
    settings = LockSettings.from_bandwidth(
        setpoint,
        actuator_hz_per_v=actuator,
        bandwidth_hz=DEFAULT_BANDWIDTH_HZ if bandwidth is None else bandwidth,
        response_s=response,
        **settings,
    )
    return settings, actuator


def register_lock_requests(server) -> None:
    """Register the lock and reference requests on ``server.control``."""
    locks = server.locks

    def lock(
        channel,
        owner,
        setpoint_hz=None,
        scan=None,
        *,
        take_over=False,
        owner_timeout_s=DEFAULT_OWNER_TIMEOUT_S,
        capture_range_hz=3e9,
        bandwidth_hz=None,
        actuator_hz_per_v=None,
        response_s=None,
        kp_v_per_hz=None,
        ki_v_per_hz_s=None,
        kd_v_s_per_hz=None,
        average=1,
        output_limits_v=None,
        rail_s=1.0,
    ):
        target = locks.get(channel)
        locks.check_owner(target, owner, take_over)
        if owner_timeout_s is not None and not (
            isinstance(owner_timeout_s, int | float) and 0 < owner_timeout_s < math.inf
        ):
            raise InputError(
                f"owner_timeout_s {owner_timeout_s!r}: expected seconds > 0, or null for none",
                parameter="owner_timeout_s",
            )
        arguments = {
            "setpoint_hz": setpoint_hz,
            "scan": scan,
            "capture_range_hz": capture_range_hz,
            "bandwidth_hz": bandwidth_hz,
            "actuator_hz_per_v": actuator_hz_per_v,
            "response_s": response_s,
            "average": average,
            "output_limits_v": output_limits_v,
            "rail_s": rail_s,
        }
        for name, value in zip(_GAINS, (kp_v_per_hz, ki_v_per_hz_s, kd_v_s_per_hz), strict=True):
            if value is not None:
                arguments[name] = value
        settings, actuator = settings_from_request(target.sink, arguments)
        rate = server.channel(channel).rate_hz
        if actuator is not None and rate > 0:
            settings.check_interval(1.0 / rate, actuator)
        return locks.lock(channel, owner, settings, take_over=take_over, timeout_s=owner_timeout_s)

    def unlock(channel, owner, take_over=False):
        return locks.unlock(channel, owner, take_over=take_over)

    def lock_status(channel=None):
        if channel is None:
            return locks.summary()
        return locks.get(channel).describe()

    def lock_keepalive(owner):
        return locks.keepalive(owner)

    def reference_status():
        anchoring = server.anchoring
        return None if anchoring is None else anchoring.describe()

    for name, handler in (
        ("lock", lock),
        ("unlock", unlock),
        ("lock_status", lock_status),
        ("lock_keepalive", lock_keepalive),
        ("reference_status", reference_status),
    ):
        server.control.register(name, handler)
