"""What a :class:`~wavemeter.simulation.Scenario` accepts: each field's type and range, and
the fields that exclude or need one another.

Every check raises :class:`~wavemeter.exceptions.InputError` naming the field
(``parameter=``), the value and what is allowed. :func:`normalised` checks each field on
its own and returns it in one spelling (an int, a float, a tuple of floats, a canonical
unit); the relations that need the device (a count per port, the band of a cascade's
coarsest stage) are checked where the scenario draws it.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ..exceptions import InputError, shown
from ..units import OPTICAL_BAND_HZ, canonical_unit, frequency_text
from .spectral_presets import SPECTRAL_PRESETS
from .thermal_presets import THERMAL_PRESETS

__all__ = [
    "MAX_PORTS",
    "MIN_SAMPLES",
    "MAX_POWER_FLUCTUATION",
    "NOT_FOR_CASCADE",
    "LASER_FIELDS",
    "normalised",
    "check_related",
    "check_cascade_fsrs",
    "check_band_covered",
    "per_port",
]

#: the most output ports a simulated MMI (or each stage) has
MAX_PORTS = 64
#: the fewest readings of a calibration sweep
MIN_SAMPLES = 4
#: the largest relative std of the source power per reading
MAX_POWER_FLUCTUATION = 0.3
#: fields a cascade is not simulated with: field -> why, as the message says it
NOT_FOR_CASCADE = {
    "fsr_hz": "the stages' FSRs are cascade_fsrs_hz's",
    "span_fsr": "a cascade's sweep covers band_hz",
    "dark_offset_w": "the detector faults are simulated for a single device",
    "dispersion_s2": "a spectral platform gives every stage the dispersion of its delay",
    "coupler_slope_sigma_per_thz": "a spectral platform gives every stage its spectral slopes",
    "responsivity_slope_sigma_per_thz": "a spectral platform gives every stage its spectral slopes",
    "thermal_drift_k": "the thermal faults are simulated for a single device",
    "platform": "the thermal devices are single devices",
    "temperature_k": "the thermal devices are single devices",
    "ramp_k": "the thermal devices are single devices",
}
#: fields that describe the laser of the laser readings (``laser`` of them)
LASER_FIELDS = (
    "laser_rate_hz",
    "laser_center_hz",
    "white_fm_hz2_per_hz",
    "flicker_fm_hz2",
    "random_walk_fm_hz2_per_s",
    "laser_drift_hz_per_s",
)


def _count(name: str, value, minimum: int, maximum: int | None = None) -> int:
    integral = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if not integral or value < minimum or (maximum is not None and value > maximum):
        allowed = f">= {minimum}" if maximum is None else f"from {minimum} to {maximum}"
        raise InputError(f"{name} must be an integer {allowed}, got {value!r}", parameter=name)
    return int(value)


def _number(name: str, value, unit: str, *, low=None, high=None, high_open=False, low_open=False):
    """A finite real number in the interval given (bounds None: open to infinity)."""
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    inside = (
        real
        and math.isfinite(value)
        and (low is None or value > low or (value == low and not low_open))
        and (high is None or value < high or (value == high and not high_open))
    )
    if not inside:
        if low is not None and high is not None:
            allowed = f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
        elif low is not None:
            allowed = f"{'>' if low_open else '>='} {low:g}"
        else:
            allowed = "finite"
        raise InputError(
            f"{name} must be a finite number {allowed}{unit}, got {value!r}", parameter=name
        )
    return float(value)


def _numbers(name: str, values, unit: str, *, length: int | None = None, **bounds) -> tuple:
    """A tuple of numbers each as :func:`_number` takes it (a single number is one)."""
    items = (values,) if isinstance(values, numbers.Real) else values
    try:
        items = tuple(items)
    except TypeError:
        raise InputError(
            f"{name} must be a number or a sequence of numbers{unit}, got {values!r}",
            parameter=name,
        ) from None
    if not items or (length is not None and len(items) != length):
        allowed = "one or more numbers" if length is None else f"{length} numbers"
        raise InputError(f"{name} must be {allowed}{unit}, got {values!r}", parameter=name)
    return tuple(_number(name, item, unit, **bounds) for item in items)


def _choice(name: str, value, allowed) -> str:
    if value not in allowed:
        raise InputError(
            f"{name} must be one of {', '.join(map(repr, allowed))}, got {value!r}",
            parameter=name,
        )
    return value


def _unit(name: str, value, kind: str) -> str:
    try:
        return canonical_unit(value, kind, name)
    except InputError as exc:
        raise InputError(str(exc), parameter=name) from exc


def _optional(function, name: str, value, *args, **kwargs):
    return None if value is None else function(name, value, *args, **kwargs)


def normalised(fields: dict) -> dict:
    """Every field checked on its own, in one spelling; ``fields`` maps name -> value.

    Raises
    ------
    InputError
        For the first field of the wrong type or out of its range.
    """
    values = dict(fields)
    positive = {"low": 0.0, "low_open": True}
    non_negative = {"low": 0.0}
    optical = {"low": OPTICAL_BAND_HZ[0], "high": OPTICAL_BAND_HZ[1]}
    values["ports"] = _count("ports", values["ports"], 3, MAX_PORTS)
    values["seed"] = _count("seed", values["seed"], 0)
    values["samples"] = _count("samples", values["samples"], MIN_SAMPLES)
    values["span_fsr"] = _optional(_number, "span_fsr", values["span_fsr"], " (FSRs)", **positive)
    values["power_w"] = _number("power_w", values["power_w"], " (W)", **positive)
    values["noise_w"] = _optional(_number, "noise_w", values["noise_w"], " (W)", **non_negative)
    values["fsr_hz"] = _optional(_number, "fsr_hz", values["fsr_hz"], " (Hz)", **positive)
    values["cascade_fsrs_hz"] = _optional(
        _numbers, "cascade_fsrs_hz", values["cascade_fsrs_hz"], " (Hz)", **positive
    )
    values["band_hz"] = _optional(_band, "band_hz", values["band_hz"])
    values["test"] = _count("test", values["test"], 0)
    values["x_unit"] = _unit("x_unit", values["x_unit"], "axis")
    values["power_unit"] = _unit("power_unit", values["power_unit"], "power")
    if values["power_unit"] == "V":
        raise InputError(
            "power_unit V is not a simulated output; use W, mW, uW, nW or dBm",
            parameter="power_unit",
        )
    values["power_fluctuation"] = _number(
        "power_fluctuation", values["power_fluctuation"], "", low=0.0, high=MAX_POWER_FLUCTUATION
    )
    values["dark_offset_w"] = _optional(_numbers, "dark_offset_w", values["dark_offset_w"], " (W)")
    values["port_noise_w"] = _optional(
        _numbers, "port_noise_w", values["port_noise_w"], " (W)", **non_negative
    )
    values["dispersion_s2"] = _optional(_number, "dispersion_s2", values["dispersion_s2"], " (s^2)")
    values["spectral"] = _optional(_choice, "spectral", values["spectral"], tuple(SPECTRAL_PRESETS))
    for name in ("coupler_slope_sigma_per_thz", "responsivity_slope_sigma_per_thz"):
        values[name] = _optional(_number, name, values[name], " (1/THz)", **non_negative)
    values["power_drift"] = _number(
        "power_drift", values["power_drift"], "", low=0.0, high=1.0, high_open=True
    )
    values["thermal_drift_k"] = _optional(
        _number, "thermal_drift_k", values["thermal_drift_k"], " (K)"
    )
    values["platform"] = _optional(_choice, "platform", values["platform"], tuple(THERMAL_PRESETS))
    values["temperature_k"] = _optional(
        _number, "temperature_k", values["temperature_k"], " (K)", **positive
    )
    values["ramp_k"] = _optional(_numbers, "ramp_k", values["ramp_k"], " (K)", length=2, **positive)
    values["repeat"] = _count("repeat", values["repeat"], 1)
    if not isinstance(values["monitor"], (bool, np.bool_)):
        raise InputError(
            f"monitor must be True or False, got {shown(values['monitor'])}", parameter="monitor"
        )
    values["monitor"] = bool(values["monitor"])
    values["laser"] = _count("laser", values["laser"], 0)
    values["laser_rate_hz"] = _optional(
        _number, "laser_rate_hz", values["laser_rate_hz"], " (Hz)", **positive
    )
    values["laser_center_hz"] = _optional(
        _number,
        "laser_center_hz",
        values["laser_center_hz"],
        " (Hz)",
        **optical,
    )
    for name, unit in (
        ("white_fm_hz2_per_hz", " (Hz^2/Hz)"),
        ("flicker_fm_hz2", " (Hz^2)"),
        ("random_walk_fm_hz2_per_s", " (Hz^2/s)"),
    ):
        values[name] = _number(name, values[name], unit, **non_negative)
    values["laser_drift_hz_per_s"] = _number(
        "laser_drift_hz_per_s", values["laser_drift_hz_per_s"], " (Hz/s)"
    )
    return values


def _band(name: str, value) -> tuple[float, float]:
    low, high = OPTICAL_BAND_HZ
    band = _numbers(name, value, " (Hz)", length=2, low=low, high=high)
    if not band[0] < band[1]:
        raise InputError(
            f"{name} must be (low, high) with low < high (Hz), got {value!r}", parameter=name
        )
    return band


def check_related(values: dict) -> None:
    """The fields that exclude or need one another (before the device is drawn).

    Raises
    ------
    InputError
        For a field a cascade is not simulated with, a band without a cascade, cascade FSRs
        that do not decrease, a temperature without a thermal platform, a temperature and a
        ramp together, noise for every port and per port together, or a laser field without
        laser readings.
    """
    if values["cascade_fsrs_hz"] is not None:
        for name, reason in NOT_FOR_CASCADE.items():
            if values[name] is not None:
                raise InputError(
                    f"{name} is not simulated for a cascade (cascade_fsrs_hz): {reason}; "
                    "leave it out",
                    parameter=name,
                )
        check_cascade_fsrs(values["cascade_fsrs_hz"])
    elif values["band_hz"] is not None:
        raise InputError(
            "band_hz is the band of a cascade (cascade_fsrs_hz); a single device's sweep is "
            "span_fsr FSRs about its centre",
            parameter="band_hz",
        )
    if values["platform"] is None:
        for name in ("temperature_k", "ramp_k"):
            if values[name] is not None:
                raise InputError(
                    f"{name} needs a thermal device: choose a platform, 'sin' or 'soi' (a "
                    "Table 1 device has no thermal coefficients)",
                    parameter="platform",
                )
    elif values["temperature_k"] is not None and values["ramp_k"] is not None:
        raise InputError(
            "temperature_k (one temperature) and ramp_k (a ramp) both set the chip "
            "temperature; give one of them",
            parameter="ramp_k",
        )
    if values["port_noise_w"] is not None and values["noise_w"] is not None:
        raise InputError(
            "give noise_w (every port) or port_noise_w (each port), not both",
            parameter="port_noise_w",
        )
    if values["laser"] == 0:
        for name in LASER_FIELDS:
            if values[name] not in (None, 0.0):
                raise InputError(
                    f"{name} describes the laser of the laser readings, and none are asked "
                    f"for (laser is 0): ask for some, or leave {name} out",
                    parameter="laser",
                )


def check_cascade_fsrs(fsrs_hz: tuple[float, ...]) -> None:
    """Two or more stages of decreasing FSR, coarsest first."""
    if len(fsrs_hz) < 2 or any(
        fine >= coarse for coarse, fine in zip(fsrs_hz[:-1], fsrs_hz[1:], strict=True)
    ):
        raise InputError(
            f"cascade_fsrs_hz {', '.join(frequency_text(value) for value in fsrs_hz)}: a "
            "cascade needs two or more stages of decreasing FSR, coarsest first (e.g. 5 THz, "
            "500 GHz, 50 GHz)",
            parameter="cascade_fsrs_hz",
        )


def per_port(name: str, values: tuple, ports: int, *, single: bool) -> np.ndarray:
    """A per-port array from a field's values: ``ports`` of them, or (``single``) one for
    every port."""
    if single and len(values) == 1:
        return np.full(ports, values[0])
    if len(values) != ports:
        allowed = f"one for all ports or {ports}" if single else f"{ports}, one per port"
        raise InputError(
            f"{name} has {len(values)} value(s) for {ports} ports: give {allowed}",
            parameter=name,
        )
    return np.asarray(values)


def check_band_covered(device, design_fsrs_hz: tuple[float, ...], band_hz) -> None:
    """A cascade's coarsest stage, as drawn, must exceed its band: else its phase repeats
    within the band and no cascade can read it."""
    coarsest = device.true_fsrs_hz[0]
    low, high = band_hz
    if coarsest <= high - low:
        raise InputError(
            f"the coarsest stage's FSR ({frequency_text(coarsest)} as drawn, design "
            f"{frequency_text(design_fsrs_hz[0])}) does not exceed the band "
            f"{frequency_text(low)} to {frequency_text(high)} ({frequency_text(high - low)}): "
            "its phase repeats within the band and no cascade can read it; give a narrower "
            "band_hz or a coarser first stage",
            parameter="band_hz",
        )
