"""Units of the quantities in data files: names, conversion to SI, plausibility.

Frequency axes come in ``Hz kHz MHz GHz THz`` or as vacuum wavelength in ``nm um m``
(``f = c / lambda`` with ``c = 299792458 m/s`` exactly). Port powers come in
``W mW uW nW dBm`` or ``V`` (a detector voltage: linear in power, relative scale).
Temperatures come in ``K`` or ``C``, times and durations in ``s ms us ns``. Inside the
package everything is SI (Hz, W, K, s).
Unit names are matched without regard to case (no two allowed units differ only in case)
and ``u`` and ``µ`` both mean micro.
"""

from __future__ import annotations

import re

import numpy as np

from .exceptions import InputError

__all__ = [
    "frequency_text",
    "SPEED_OF_LIGHT_M_S",
    "FREQUENCY_UNITS",
    "WAVELENGTH_UNITS",
    "POWER_UNITS",
    "TEMPERATURE_UNITS",
    "TIME_UNITS",
    "OPTICAL_BAND_HZ",
    "SENTINEL_DBM",
    "canonical_unit",
    "axis_to_hz",
    "hz_to_axis",
    "check_optical_frequency",
    "power_to_w",
    "w_to_power",
    "temperature_to_k",
    "parse_quantity",
    "parse_frequency_hz",
    "parse_optical_frequency_hz",
    "parse_power_w",
    "parse_time_s",
    "seconds_per_unit",
    "decimal_scale",
]

SPEED_OF_LIGHT_M_S = 299_792_458.0

#: unit -> decimal exponent of its size in Hz
FREQUENCY_UNITS = {"Hz": 0, "kHz": 3, "MHz": 6, "GHz": 9, "THz": 12}
#: unit -> decimal exponent of its size in m
WAVELENGTH_UNITS = {"nm": -9, "um": -6, "m": 0}
#: unit -> decimal exponent of its size in W; dBm is logarithmic; V is linear, relative scale
POWER_UNITS = {"W": 0, "mW": -3, "uW": -6, "nW": -9, "dBm": None, "V": 0}
#: unit -> offset (K) added to a value in that unit
TEMPERATURE_UNITS = {"K": 0.0, "C": 273.15}
#: unit -> decimal exponent of its size in s
TIME_UNITS = {"s": 0, "ms": -3, "us": -6, "ns": -9}
#: plausible optical frequencies (Hz): 100-1000 THz, i.e. about 300-3000 nm
OPTICAL_BAND_HZ = (100e12, 1000e12)
#: dBm readings at or below this are a power meter's "no reading" code
SENTINEL_DBM = -200.0

_KINDS = {
    "frequency": FREQUENCY_UNITS,
    "wavelength": WAVELENGTH_UNITS,
    "axis": {**FREQUENCY_UNITS, **WAVELENGTH_UNITS},
    "power": POWER_UNITS,
    "temperature": TEMPERATURE_UNITS,
    "time": TIME_UNITS,
}
_ALIASES = {
    **{"µm": "um", "μm": "um", "µw": "uW", "μw": "uW", "µs": "us", "μs": "us", "sec": "s"},
    **{"°c": "C", "degc": "C", "deg c": "C"},
}
_LOOKUP = {
    **{name.lower(): name for units in _KINDS.values() for name in units},
    **{alias: name for alias, name in _ALIASES.items()},
}


def decimal_scale(exponent: int) -> tuple[float, bool]:
    """How ``values * 10**exponent`` is worked out, correctly rounded: ``(10.0**|exponent|,
    True)`` to multiply by, or for a negative exponent ``(10.0**-exponent, False)`` to
    divide by (``1e-3`` is not exact in binary; ``1000.0`` is)."""
    return 10.0 ** abs(exponent), exponent >= 0


def _scaled(values: np.ndarray, exponent: int) -> np.ndarray:
    """``values * 10**exponent``, correctly rounded (:func:`decimal_scale`)."""
    factor, multiply = decimal_scale(exponent)
    return values * factor if multiply else values / factor


def _wavelength_constant(unit: str) -> float:
    """``c`` in (wavelength unit) * Hz: exact in float64 for nm, um and m."""
    return SPEED_OF_LIGHT_M_S * 10.0 ** (-WAVELENGTH_UNITS[unit])


def canonical_unit(unit: str, kind: str, label: str | None = None) -> str:
    """The canonical spelling of ``unit`` (e.g. ``"thz"`` -> ``"THz"``, ``"µm"`` -> ``"um"``).

    Parameters
    ----------
    unit : str
        Unit as written in a file header or on the command line.
    kind : {"frequency", "wavelength", "axis", "power", "temperature"}
        What the unit must measure; ``"axis"`` accepts frequency and wavelength units.
    label : str, optional
        What the unit belongs to (``"column 'P1_mW'"``, ``"--fsr"``), named in the error.

    Raises
    ------
    InputError
        When the unit is unknown or of another kind; the message lists the allowed units.
    """
    allowed = _KINDS[kind]
    name = _LOOKUP.get(str(unit).strip().lower())
    if name not in allowed:
        where = f"{label}: " if label else ""
        raise InputError(f"{where}unknown {kind} unit {unit!r}; allowed: {', '.join(allowed)}")
    return name


def axis_to_hz(values, unit: str, column: str = "frequency axis") -> np.ndarray:
    """Frequency (Hz) from a frequency or vacuum-wavelength axis, checked to be optical.

    Parameters
    ----------
    values : array_like, shape (N,)
        Axis values in ``unit``.
    unit : str
        A frequency unit (Hz..THz) or a wavelength unit (nm, um, m).
    column : str
        Name of the axis, used in error messages.

    Returns
    -------
    ndarray, shape (N,), Hz

    Raises
    ------
    InputError
        For an unknown unit, or values that are not optical frequencies in that unit
        (the message suggests the unit they look like).
    """
    unit = canonical_unit(unit, "axis", f"column {column!r}")
    array = np.asarray(values, dtype=float)
    if unit in FREQUENCY_UNITS:
        frequency = _scaled(array, FREQUENCY_UNITS[unit])
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            frequency = _wavelength_constant(unit) / array
    check_optical_frequency(frequency, array, unit, column)
    return frequency


def hz_to_axis(frequency_hz, unit: str) -> np.ndarray:
    """Axis values in ``unit`` (frequency or vacuum wavelength) from frequencies (Hz)."""
    unit = canonical_unit(unit, "axis")
    frequency = np.asarray(frequency_hz, dtype=float)
    if unit in FREQUENCY_UNITS:
        return _scaled(frequency, -FREQUENCY_UNITS[unit])
    return _wavelength_constant(unit) / frequency


def _finite_range(values: np.ndarray) -> tuple[float, float] | None:
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return None
    return float(finite.min()), float(finite.max())


def _plausible(frequency_range: tuple[float, float]) -> bool:
    low, high = OPTICAL_BAND_HZ
    slack = 1e-12  # unit conversions round; the band edges are not sharp anyway
    return low * (1 - slack) <= frequency_range[0] and frequency_range[1] <= high * (1 + slack)


def check_optical_frequency(frequency_hz, raw_values, unit: str | None, column: str) -> None:
    """Raise InputError unless the finite frequencies lie in the optical band (100-1000 THz).

    Parameters
    ----------
    frequency_hz : ndarray, shape (N,)
        Converted frequencies (Hz).
    raw_values : ndarray, shape (N,)
        The values as written, used to suggest the unit they look like.
    unit : str or None
        The unit the values were read in (None: no unit given).
    column : str
        Name of the axis, for the message.
    """
    converted = _finite_range(np.asarray(frequency_hz, dtype=float))
    if converted is None or _plausible(converted):
        return
    raw = _finite_range(np.asarray(raw_values, dtype=float))
    guess = optical_unit_guess(raw_values)
    shown = f"{raw[0]:.6g}-{raw[1]:.6g}" if raw else "the values"
    label = f"labelled {unit}" if unit else "without a unit"
    if guess:
        hint = f"look like {guess}; give the axis unit {guess}"
    else:
        hint = "are not optical (100-1000 THz, 300-3000 nm) in any unit; check the column"
    raise InputError(f"column {column!r}: values {shown} {label} {hint}", parameter="x_unit")


def optical_unit_guess(values) -> str | None:
    """The frequency or wavelength unit (``"THz"``, ``"nm"``...) in which all the finite
    ``values`` would be optical (100-1000 THz), or None when there is none."""
    raw = _finite_range(np.asarray(values, dtype=float))
    if raw is None:
        return None
    guesses = [name for name in _KINDS["axis"] if _plausible(_range_in(raw, name))]
    return guesses[0] if guesses else None


def _range_in(raw: tuple[float, float], unit: str) -> tuple[float, float]:
    if unit in FREQUENCY_UNITS:
        low, high = _scaled(np.array(raw), FREQUENCY_UNITS[unit])
    elif raw[0] > 0:
        high, low = _wavelength_constant(unit) / np.array(raw)
    else:
        return (-np.inf, np.inf)
    return float(low), float(high)


def power_to_w(values, unit: str, column: str = "power") -> np.ndarray:
    """Power in W (or, for ``V``, the voltage as a relative linear power) from ``unit``.

    ``dBm`` converts as ``1 mW * 10**(value / 10)``. The result is a new float64 array.
    """
    unit = canonical_unit(unit, "power", f"column {column!r}")
    array = np.asarray(values, dtype=float)
    if unit == "dBm":
        return np.power(10.0, array / 10.0) / 1e3
    return _scaled(array, POWER_UNITS[unit])


def w_to_power(values_w, unit: str) -> np.ndarray:
    """Values in ``unit`` from powers in W; ``dBm`` of a reading <= 0 W is ``-inf``."""
    unit = canonical_unit(unit, "power")
    array = np.asarray(values_w, dtype=float)
    if unit == "dBm":
        positive = np.where(array > 0, array, 1.0)
        return np.where(array > 0, 10.0 * (np.log10(positive) + 3.0), -np.inf)
    return _scaled(array, -POWER_UNITS[unit])


def temperature_to_k(values, unit: str, column: str = "temperature") -> np.ndarray:
    """Temperature (K) from values in ``K`` or ``C`` (degrees Celsius)."""
    unit = canonical_unit(unit, "temperature", f"column {column!r}")
    return np.asarray(values, dtype=float) + TEMPERATURE_UNITS[unit]


_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\d\s].*)?$")
_EXAMPLES = {
    "frequency": "50GHz, 49.69 GHz, 5e10",
    "axis": "193.4THz, 1550nm, 1.934e14",
    "power": "1mW, 5e-7 W, -30dBm",
    "time": "1ms, 2.5 s, 10us",
}


def parse_quantity(text, kind: str, name: str = "value") -> tuple[float, str | None]:
    """The number and canonical unit of text such as ``50GHz``, ``1 mW`` or ``5e-7``.

    Parameters
    ----------
    text : str
        A number with an optional unit, with or without a space between them.
    kind : {"frequency", "axis", "power", "time"}
        What the unit must measure (``"axis"``: frequency or vacuum wavelength).
    name : str
        What the value is (``"--fsr"``, ``"fsr_hz"``), named in the error.

    Returns
    -------
    number : float
        The number as written.
    unit : str or None
        Its canonical unit, None for a bare number.

    Raises
    ------
    InputError
        When the text is not a finite number with an optional unit of that kind.
    """
    match = _QUANTITY.match(str(text))
    if not match:
        raise InputError(
            f"{name} {text!r} is not a number with an optional unit (e.g. {_EXAMPLES[kind]}); "
            f"units: {', '.join(_KINDS[kind])}"
        )
    number, unit = match.groups()
    value = float(number)
    if not np.isfinite(value):
        raise InputError(f"{name} {text!r} is not a finite number")
    return value, canonical_unit(unit.strip(), kind, name) if unit else None


def _in_si(number: float, unit: str | None, units: dict) -> float:
    """A parsed number in its SI unit: scaled by ``units``' power of ten for ``unit``, as
    it is for a bare number (None)."""
    return float(_scaled(np.float64(number), units[unit] if unit else 0))


def parse_frequency_hz(text, name: str = "frequency") -> float:
    """A frequency (Hz) from text such as ``50GHz``, ``49.69 GHz`` or ``5e10`` (Hz).

    Raises
    ------
    InputError
        When the text is not a number with an optional frequency unit.
    """
    number, unit = parse_quantity(text, "frequency", name)
    return _in_si(number, unit, FREQUENCY_UNITS)


def parse_optical_frequency_hz(text, name: str = "frequency") -> float:
    """An optical frequency (Hz) from a frequency or a vacuum wavelength: ``193.4THz``,
    ``1550nm``, ``1.934e14`` (Hz).

    Raises
    ------
    InputError
        When the text is not a number with an optional frequency or wavelength unit, or a
        wavelength is not positive.
    """
    number, unit = parse_quantity(text, "axis", name)
    if unit in WAVELENGTH_UNITS:
        if not number > 0:
            raise InputError(f"{name} {text!r}: a wavelength must be > 0")
        return float(_wavelength_constant(unit) / np.float64(number))
    return _in_si(number, unit, FREQUENCY_UNITS)


def parse_power_w(text, name: str = "power") -> float:
    """A power (W) from text such as ``1mW``, ``5e-7 W``, ``-30dBm`` or ``1e-3`` (W).

    Raises
    ------
    InputError
        When the text is not a number with an optional power unit; ``V`` (a relative
        detector scale) is not a power.
    """
    number, unit = parse_quantity(text, "power", name)
    if unit == "V":
        raise InputError(f"{name} {text!r}: V is a relative detector scale, not a power")
    if unit == "dBm":
        return float(power_to_w(number, "dBm"))
    return _in_si(number, unit, POWER_UNITS)


def seconds_per_unit(unit: str) -> float | None:
    """Seconds per time ``unit`` (``s ms us ns``, ``µs``, ``sec``; any case); None when
    ``unit`` is not a time unit."""
    name = _LOOKUP.get(unit.strip().lower())
    return _in_si(1.0, name, TIME_UNITS) if name in TIME_UNITS else None


def parse_time_s(text, name: str = "time") -> float:
    """A time or duration (s) from text such as ``1ms``, ``2.5 s`` or ``1e-3`` (s).

    Raises
    ------
    InputError
        When the text is not a number with an optional time unit.
    """
    number, unit = parse_quantity(text, "time", name)
    return _in_si(number, unit, TIME_UNITS)


#: SI prefixes of frequencies, largest first
_FREQUENCY_PREFIXES = ((1e12, "THz"), (1e9, "GHz"), (1e6, "MHz"), (1e3, "kHz"))


def frequency_text(frequency_hz: float, digits: int = 6) -> str:
    """A frequency with the largest SI prefix that keeps it >= 1, ``digits`` significant:
    ``5 THz``, ``496.734 GHz``."""
    for factor, unit in _FREQUENCY_PREFIXES:
        if abs(frequency_hz) >= factor:
            return f"{frequency_hz / factor:.{digits}g} {unit}"
    return f"{frequency_hz:.{digits}g} Hz"
