"""Checks that need every row of a column, made chunk by chunk: plausible power units.

As a frequency axis whose values cannot be optical in its unit is refused with the unit
they look like, so are port columns whose readings cannot be powers in the unit their
name gives:

- a port column with no positive reading in a linear unit (W, mW, uW, nW, V, none): light
  gives positive readings somewhere; such values are dBm;
- a port column labelled dBm whose greatest reading is positive and at most
  :data:`WATT_LIKE_MAX_DBM`, and whose least is no more negative than minus half the
  greatest: as dBm every reading would be within 2.3 % of 1 mW, with no fringe; they are
  powers in W (at most 100 mW; small negative ones are a detector's noise or offset);
- a port column labelled W, mW, uW or nW with more than half of its readings at or below
  :data:`DBM_LIKE_BELOW` in that unit: light is no negative power, and a detector's offset
  makes only small negative readings; they are dBm.

The last two hold for units a column's name (or the file) gives; a unit the caller gives
(``power_unit``) is taken as said. Readings that are invalid anyway (NaN, "no reading"
codes, implausible dBm) are left out. An axis without a unit keeps the unit its first
finite values chose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from .power_codes import SENTINEL_W, raw_power_problems

__all__ = ["ColumnChecks", "WATT_LIKE_MAX_DBM", "DBM_LIKE_BELOW"]

#: readings labelled dBm whose greatest lies in (0, this] and whose least is at or above
#: minus half of it are powers in W
WATT_LIKE_MAX_DBM = 0.1
#: readings labelled W, mW, uW or nW of which more than half are at or below this (in the
#: column's unit) are dBm
DBM_LIKE_BELOW = -1.0
_LINEAR_UNITS = ("W", "mW", "uW", "nW")


@dataclass
class _PortReadings:
    """What a port column's readings were so far."""

    unit: str
    labelled: bool
    finite: bool = False  # a finite reading below the "no reading" codes was seen
    positive: bool = False  # ... and a positive one
    count: int = 0  # valid readings
    low: float = np.inf  # their least
    high: float = -np.inf  # their greatest
    dbm_like: int = 0  # valid readings at or below DBM_LIKE_BELOW


class ColumnChecks:
    """Checks that need every row of a column (see the module's text), fed chunk by chunk;
    :meth:`finish` makes them once every row was seen."""

    def __init__(self):
        self._ports: dict[str, _PortReadings] = {}
        self._units: dict[str, str] = {}

    def port(self, name: str, raw: np.ndarray, unit: str, labelled: bool = True) -> None:
        """Note a chunk of a port column's raw readings (shape (m,)) in ``unit`` (``""``:
        relative); ``labelled``: the unit comes from the file, not from the caller."""
        seen = self._ports.setdefault(name, _PortReadings(unit, labelled))
        with np.errstate(invalid="ignore"):
            finite = raw[np.isfinite(raw) & (raw < SENTINEL_W)]
            nonfinite, sentinel, implausible = raw_power_problems(raw, unit)
            valid = raw[~(nonfinite | sentinel | implausible)]
        seen.finite = seen.finite or finite.size > 0
        seen.positive = seen.positive or bool(np.any(finite > 0))
        if valid.size:
            seen.count += valid.size
            seen.low = min(seen.low, float(valid.min()))
            seen.high = max(seen.high, float(valid.max()))
            seen.dbm_like += int(np.count_nonzero(valid <= DBM_LIKE_BELOW))

    def axis_unit(self, key: str) -> str | None:
        """The unit an axis without one was read in so far (None: none chosen yet)."""
        return self._units.get(key)

    def choose_axis_unit(self, key: str, unit: str) -> None:
        """Keep ``unit`` for the axis ``key`` from now on."""
        self._units.setdefault(key, unit)

    def finish(self) -> None:
        """Raise InputError (``parameter="power_unit"``) for the first port column whose
        readings cannot be powers in its unit."""
        for name, seen in self._ports.items():
            unit = seen.unit
            if unit != "dBm" and seen.finite and not seen.positive:
                raise InputError(
                    f"column {name!r}{f' (labelled {unit})' if unit else ''} has no positive "
                    "reading: are these dBm? give the power unit dBm (power_unit)",
                    parameter="power_unit",
                )
            if not seen.labelled or not seen.count:
                continue
            shown = f"values {seen.low:.4g} to {seen.high:.4g} labelled {unit}"
            if unit == "dBm" and 0 < seen.high <= WATT_LIKE_MAX_DBM and seen.low >= -seen.high / 2:
                raise InputError(
                    f"column {name!r}: {shown} look like W: none is above {WATT_LIKE_MAX_DBM:g} "
                    "and the negative ones are small beside the positive ones (a detector's noise "
                    "or offset), while as dBm every reading would lie within 2.3 % of 1 mW; give "
                    "the power unit W",
                    parameter="power_unit",
                )
            if unit in _LINEAR_UNITS and 2 * seen.dbm_like > seen.count:
                raise InputError(
                    f"column {name!r}: {shown} look like dBm: {seen.dbm_like} of "
                    f"{seen.count} readings are {DBM_LIKE_BELOW:g} {unit} or less, and light is "
                    "no negative power beyond a small detector offset; give the power unit dBm",
                    parameter="power_unit",
                )
