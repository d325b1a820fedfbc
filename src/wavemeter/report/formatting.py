"""How the report writes numbers, units and names: shared by the page and the figures.

Errors, ratios and noise are shown with three significant digits (``1.00``, ``0.387``,
``310``), so a ratio of 1.002 reads ``1.00`` and not ``1``. Port names lose the unit
suffix of their file column (``p1_dBm`` -> ``p1``): the figures show every port in the
axis unit, whatever unit the file used.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..exceptions import InputError
from ..units import canonical_unit

__all__ = [
    "significant",
    "scientific",
    "scientific_with_error",
    "with_error",
    "port_label",
    "power_unit",
    "frequency_error_unit",
    "SIGNIFICANT_DIGITS",
    "PHASE_COEFFICIENT_NAMES",
]

SIGNIFICANT_DIGITS = 3
#: names of the phase coefficients ``c_i`` (s^i) of a wide-band calibration, by order
PHASE_COEFFICIENT_NAMES = {
    1: "delay",
    2: "group-delay dispersion",
    3: "third-order dispersion",
    4: "fourth-order dispersion",
}
#: display units of power, largest first: (W per unit, name)
POWER_DISPLAY_UNITS = ((1.0, "W"), (1e-3, "mW"), (1e-6, "uW"), (1e-9, "nW"))
_BRACKETED_UNIT = re.compile(r"^(.*?\S)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")
_SUFFIXED_UNIT = re.compile(r"^(.*?[^\s_\-])[\s_\-]+([^\s_\-]+)$")


def significant(value: float, digits: int = SIGNIFICANT_DIGITS) -> str:
    """``value`` with ``digits`` significant digits in positional notation, zeros kept.

    ``significant(1.002) == "1.00"``, ``significant(0.38742) == "0.387"``,
    ``significant(309.58) == "310"``, ``significant(3512.4) == "3510"``; NaN and
    infinities as ``"nan"``, ``"inf"``.
    """
    value = float(value)
    if not math.isfinite(value):
        return str(value)
    if value == 0.0:
        return f"{0.0:.{digits - 1}f}"
    decimals = digits - 1 - math.floor(math.log10(abs(value)))
    rounded = round(value, decimals)
    if rounded != 0.0 and math.floor(math.log10(abs(rounded))) > digits - 1 - decimals:
        decimals -= 1  # rounding carried into a new digit (9.996 -> 10.0)
        rounded = round(value, decimals)
    return f"{rounded:.{max(decimals, 0)}f}"


def scientific(value: float, digits: int = SIGNIFICANT_DIGITS) -> str:
    """``value`` in exponent notation with ``digits`` significant digits: ``2.00e-08``."""
    return f"{float(value):.{digits - 1}e}"


def scientific_with_error(value: float, error: float | None, separator: str = " ± ") -> str:
    """``value ± error`` in exponent notation: the error with ``SIGNIFICANT_DIGITS``
    significant digits, the value to the same decimal place (``1.90403591e-11 ±
    1.47e-17``); without a positive error, the value with six significant digits."""
    value = float(value)
    if error is None or not error > 0 or not math.isfinite(value):
        return f"{value:.5e}"
    magnitude = math.floor(math.log10(abs(value))) if value != 0 else None
    spread = math.floor(math.log10(error))
    digits = SIGNIFICANT_DIGITS
    if magnitude is not None:
        digits = max(SIGNIFICANT_DIGITS, magnitude - spread + SIGNIFICANT_DIGITS)
    return f"{value:.{digits - 1}e}{separator}{float(error):.{SIGNIFICANT_DIGITS - 1}e}"


def port_label(name: str) -> str:
    """A port column's name without its power unit: ``"p1_dBm"`` -> ``"p1"``.

    A bracketed unit (``"Port 3 [uW]"``) or a trailing token that is a power unit (``W mW
    uW nW dBm V``) is removed; other names are kept (``"DC CH1"``).
    """
    for pattern in (_BRACKETED_UNIT, _SUFFIXED_UNIT):
        found = pattern.match(name.strip())
        if found:
            try:
                canonical_unit(found.group(2), "power")
            except InputError:
                continue
            return found.group(1)
    return name


def power_unit(powers_w) -> tuple[float, str]:
    """Display scale (W per unit) and name for powers in W: the largest unit below the peak."""
    values = np.abs(np.asarray(powers_w, dtype=float))
    peak = float(np.max(values)) if values.size else 1.0
    for scale, name in POWER_DISPLAY_UNITS:
        if peak >= scale:
            return scale, name
    return POWER_DISPLAY_UNITS[-1]


def frequency_error_unit(error_hz) -> tuple[float, str]:
    """Display scale (Hz per unit) and name for frequency errors: MHz below 1 GHz, else GHz."""
    values = np.abs(np.asarray(error_hz, dtype=float))
    peak = float(np.max(values)) if values.size else 0.0
    return (1e9, "GHz") if peak >= 1e9 else (1e6, "MHz")


def with_error(value, error, scale: float = 1.0) -> str:
    """``value ± error`` (both divided by ``scale``) with three significant digits in the
    error and the value to the same decimal place."""
    if error is None or not error > 0:
        return significant(value / scale, 6)
    digits = max(0, 2 - math.floor(math.log10(error / scale)))
    return f"{value / scale:.{digits}f} ± {error / scale:.{digits}f}"
