"""Rows of a file in SI units: conversion, and the rules that make a reading invalid.

:func:`convert_rows` turns any run of consecutive rows of a file into a
:class:`~wavemeter.io.Table` in SI units, each invalid row flagged with its reason (NaN or
inf, power-meter "no reading" codes, dBm readings above :data:`MAX_DBM`, no light, a bad
monitor reading); whole-file reading, chunked reading and a stream's lines share it.
:class:`PlainRowConverter` applies the same rules to one row of a live readout, fast.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from ..exceptions import InputError
from ..units import (
    FREQUENCY_UNITS,
    WAVELENGTH_UNITS,
    axis_to_hz,
    canonical_unit,
    power_to_w,
    temperature_to_k,
)
from .columns import WAVELENGTH_WORD, Role
from .plan import ColumnPlan
from .power_codes import MAX_DBM, raw_power_problems
from .table import InvalidRows, Table

if TYPE_CHECKING:
    from .checks import ColumnChecks

__all__ = [
    "convert_rows",
    "PlainRowConverter",
    "NO_LIGHT_REASON",
]

#: the reason a row whose ports sum to zero or less is invalid (dark readings have it)
NO_LIGHT_REASON = "port powers sum to <= 0: no light"


def convert_rows(
    plan: ColumnPlan,
    data: dict[str, np.ndarray],
    start: int,
    row_label,
    checks: ColumnChecks,
) -> Table:
    """Consecutive rows of a file as a Table in SI units, invalid rows flagged.

    Parameters
    ----------
    plan : ColumnPlan
        The columns and units.
    data : dict of str to ndarray, shape (m,) or (m, k)
        The fields of ``plan.fields`` for these rows, samples along the first axis.
    start : int
        Zero-based index of the first row among the file's data rows.
    row_label : callable
        Names data row ``i`` (file-wide) as the user finds it.
    checks : ColumnChecks
        Whole-column checks, fed with these rows (call its ``finish`` after the last).

    Returns
    -------
    Table
        With ``row_index`` ``start .. start + m - 1`` and ``rows_in_file`` the rows read so
        far (``start + m``).
    """
    rows = len(data[plan.fields[0]])
    invalid = InvalidRows(rows)
    powers = _ports_array(plan, data, rows, invalid, checks)
    fields: dict[str, object] = {}
    singles = plan.singles
    for key in ("x", "coarse"):
        if key in singles:
            role = singles[key]
            raw = data[role.name]
            invalid.add(~np.isfinite(raw), f"{role.name} is NaN, empty or inf")
            chosen = checks.axis_unit(key)
            if role.unit is None and chosen is not None:
                role = dataclasses.replace(role, unit=chosen)
            with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
                fields[f"{key}_hz"], unit = _axis_hz(role, raw, key)
            if np.isfinite(raw).any():
                checks.choose_axis_unit(key, unit)
            invalid.add(~np.isfinite(fields[f"{key}_hz"]), f"{role.name} is not a frequency")
            fields[f"{key}_column"] = role.name
            if key == "x":
                fields["x_unit"] = unit
    if "monitor" in singles:
        monitor = singles["monitor"]
        monitor_w, reasons = _power_column(monitor.name, data[monitor.name], plan.monitor_unit)
        problems = np.logical_or.reduce([mask for mask, _ in reasons])
        invalid.add(problems, f"{monitor.name} is NaN, inf, implausible or a 'no reading' code")
        with np.errstate(invalid="ignore"):
            invalid.add(~(monitor_w > 0), f"{monitor.name} is <= 0")
        fields["monitor_w"] = monitor_w
        fields["monitor_column"] = monitor.name
    if "temperature" in singles:
        temperature = singles["temperature"]
        fields["temperature_k"] = _temperature_k(plan, data[temperature.name])
        invalid.add(
            ~np.isfinite(fields["temperature_k"]), f"{temperature.name} is NaN, empty or inf"
        )
        fields["temperature_column"] = temperature.name
    return Table(
        source=plan.path,
        powers_w=powers,
        port_names=plan.port_names,
        port_units=plan.port_units,
        invalid_code=invalid.code,
        invalid_reasons=tuple(invalid.reasons),
        row_index=np.arange(start, start + rows),
        rows_in_file=start + rows,
        row_label=row_label,
        kept={name: data[name] for name in plan.request.keep},
        **fields,
    )


def _temperature_k(plan: ColumnPlan, raw: np.ndarray) -> np.ndarray:
    """The temperature column's values (K; NaN and inf where not a temperature)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return temperature_to_k(raw, plan.temperature_unit, plan.singles["temperature"].name)


class PlainRowConverter:
    """One row of port powers (and a temperature) that :func:`convert_rows` finds valid,
    converted to the same numbers without building a table.

    ``convert_rows`` names what is wrong with each invalid row, at a cost of ~70 us per
    call for three ports (~190 us for nine) whatever the number of rows: too slow for a
    live readout's one row at a time. This applies its rules (:func:`raw_power_problems`,
    the conversion, :func:`_no_light`, a finite temperature) to one row and gives up on any
    row they refuse, which ``convert_rows`` then reads and names. Only for plans of port
    columns (and a temperature column): an axis or coarse column without a unit takes the
    unit ``convert_rows`` chose from its first values.
    """

    def __init__(self, plan: ColumnPlan):
        groups: dict[str | None, list[int]] = {}
        for index, unit in enumerate(plan.role_units):
            groups.setdefault(unit, []).append(index)
        self._plan = plan
        self._ports = [
            (unit, [plan.ports[k].name for k in members], np.array(members))
            for unit, members in groups.items()
        ]
        self._temperature = plan.singles.get("temperature")

    @classmethod
    def of(cls, plan: ColumnPlan) -> PlainRowConverter | None:
        """For a plan of 1-D port columns and at most a temperature column; else None."""
        if set(plan.singles) - {"temperature"} or len(plan.port_names) != len(plan.ports):
            return None
        return cls(plan)

    def convert(self, values: dict[str, float]) -> tuple[np.ndarray, float | None] | None:
        """Powers (n,) in W and the temperature (K, or None without a temperature column)
        of a row's values by field name; None for a row ``convert_rows`` would flag."""
        powers_w = np.empty(len(self._plan.ports))
        for unit, names, members in self._ports:
            raw = np.array([values[name] for name in names])
            if any(mask.any() for mask in raw_power_problems(raw, unit)):
                return None
            with np.errstate(over="ignore"):
                powers_w[members] = power_to_w(raw, unit or "W", names[0])
        if not np.isfinite(powers_w).all() or _no_light(powers_w):
            return None
        if self._temperature is None:
            return powers_w, None
        kelvin = float(_temperature_k(self._plan, np.array([values[self._temperature.name]]))[0])
        return (powers_w, kelvin) if math.isfinite(kelvin) else None


# ---------------------------------------------------------------------------- units
def _axis_hz(role: Role, values: np.ndarray, key: str) -> tuple[np.ndarray, str]:
    """Axis in Hz and the unit used; without a unit, the one unit that makes it optical."""
    parameter = "x_unit" if key == "x" else None
    if role.unit is not None:
        try:
            return axis_to_hz(values, role.unit, role.name), canonical_unit(role.unit, "axis")
        except InputError as exc:
            raise InputError(str(exc), parameter=parameter) from exc
    leaf = role.name.rsplit("/", 1)[-1]
    units = WAVELENGTH_UNITS if WAVELENGTH_WORD.search(leaf.lower()) else FREQUENCY_UNITS
    for unit in units:
        try:
            return axis_to_hz(values, unit, role.name), unit
        except InputError:
            continue
    kind = "wavelength" if units is WAVELENGTH_UNITS else "frequency"
    raise InputError(
        f"column {role.name!r} has no unit and its values are not optical in any {kind} "
        "unit; name it like frequency_hz or wavelength_nm, or give its unit"
        + (" (x_unit)" if parameter else ""),
        parameter=parameter,
    )


def _no_light(powers_w: np.ndarray) -> np.ndarray:
    """Readings (..., n) whose ports do not sum to more than zero (NaN included)."""
    with np.errstate(invalid="ignore", over="ignore"):
        return ~(powers_w.sum(axis=-1) > 0)


def _power_column(name: str, raw: np.ndarray, unit: str) -> tuple[np.ndarray, list[tuple]]:
    """Powers (W) from raw readings, and ``(mask, reason)`` for each kind of bad reading:
    NaN/inf, power-meter sentinels, dBm above :data:`MAX_DBM`, values that overflow."""
    nonfinite, sentinel, implausible = raw_power_problems(raw, unit)
    with np.errstate(over="ignore", invalid="ignore"):
        values = power_to_w(raw, unit or "W", name)
    overflow = ~np.isfinite(values) & ~nonfinite
    code = _first(raw, sentinel)
    reasons = [
        (nonfinite, f"{name} is NaN, empty or inf"),
        (sentinel, f"{name} is a power-meter 'no reading' code {code}"),
        (implausible, f"{name} is above {MAX_DBM:g} dBm, more than a detector reads"),
        (overflow, f"{name} is too large to be a power"),
    ]
    return values, reasons


def _ports_array(
    plan: ColumnPlan, data: dict, rows: int, invalid: InvalidRows, checks: ColumnChecks
) -> np.ndarray:
    """Port readings (m, n) in W; flags bad readings in ``invalid``."""
    columns = []
    names = iter(plan.port_names)
    for role, unit in zip(plan.ports, plan.role_units, strict=True):
        values = data[role.name]
        parts = [values[:, k] for k in range(values.shape[1])] if values.ndim == 2 else [values]
        for raw in parts:
            name = next(names)
            checks.port(name, raw, unit, labelled=plan.request.power_unit is None)
            values_w, reasons = _power_column(name, raw, unit)
            for mask, reason in reasons:
                invalid.add(mask, reason)
            columns.append(values_w)
    powers = np.column_stack(columns) if rows else np.empty((0, len(columns)))
    invalid.add(_no_light(powers), NO_LIGHT_REASON)
    return powers


def _first(raw: np.ndarray, mask: np.ndarray) -> str:
    return f"{raw[mask][0]:g}" if mask.any() else ""
