"""Reading a table of readings: open the file by its format, find the columns, convert to SI.

Invalid rows (NaN or inf, power-meter "no reading" codes, dBm readings above
:data:`MAX_DBM`, no light, a bad monitor reading) are flagged with their reason and file
line; they are an error unless the caller allows them. Every error names the file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import InputError, WavemeterError
from ..units import (
    FREQUENCY_UNITS,
    WAVELENGTH_UNITS,
    axis_to_hz,
    canonical_unit,
    power_to_w,
    temperature_to_k,
)
from .columns import WAVELENGTH_WORD, ColumnRequest, Role, find_roles, known_unit, split_unit
from .formats import open_source
from .source import MAX_BYTES, Source
from .table import InvalidRows, Table

__all__ = ["read_table", "SENTINEL_W", "SENTINEL_DBM", "MAX_DBM", "MAX_PORTS", "NO_LIGHT_REASON"]

#: raw readings above this (any linear unit) are instrument "no reading" codes (9.91e37)
SENTINEL_W = 1e20
#: dBm readings at or below this are a power meter's "no reading" code
SENTINEL_DBM = -200.0
#: dBm readings above this (1 kW) are not a detector's reading: flagged invalid
MAX_DBM = 60.0
#: the reason a row whose ports sum to zero or less is invalid (dark readings have it)
NO_LIGHT_REASON = "port powers sum to <= 0: no light"
#: the most ports a 2-D port array may have; the other axis holds the samples
MAX_PORTS = 64


def read_table(
    path,
    request: ColumnRequest | None = None,
    *,
    need_x: bool = True,
    find_extras: bool = True,
    allow_invalid: bool = False,
    max_bytes: int = MAX_BYTES,
    find_temperature: bool | None = None,
) -> Table:
    """Read readings from a data file, find the columns by name and convert to SI.

    Parameters
    ----------
    path : str or Path
        CSV/TSV (header row; delimiter sniffed), HDF5, MAT (v5 or v7.3), NPZ or Parquet;
        ``"-"`` reads standard input. A pipe or device is read once.
    request : ColumnRequest, optional
        Columns and units chosen by the user; anything left None is found by name.
    need_x : bool
        Whether a frequency/wavelength column must exist (calibration sweeps, test files).
    find_extras : bool
        Look for a power monitor and a temperature column by name. A temperature found
        by name without a unit is left out; one named in ``request`` must have a unit.
    allow_invalid : bool
        Keep invalid rows (flagged in ``Table.invalid``) instead of raising.
    max_bytes : int
        The most bytes the values read from the file may take (float64), the largest text
        file and the most read from a pipe; checked against what the file declares before
        anything is read. Default :data:`~wavemeter.io.MAX_BYTES` (2 GiB).
    find_temperature : bool, optional
        Look for a temperature column by name (readings for a calibration that needs the
        chip temperature); default ``find_extras``.

    Returns
    -------
    Table

    Raises
    ------
    InputError
        For a missing or empty file, missing, duplicate or ambiguous columns, unknown
        units, non-numeric cells, implausible values, and (unless ``allow_invalid``)
        invalid rows; ``parameter`` names the argument or request field that resolves it.
    FileFormatError
        For a file that is foreign, damaged, truncated, too large or unsafe to read.
        Every message starts with the file name.
    """
    path = Path(path)
    request = request or ColumnRequest()
    try:
        extras = (find_extras, find_extras if find_temperature is None else find_temperature)
        return _read(path, request, need_x, extras, allow_invalid, max_bytes)
    except InputError as exc:
        if str(exc).startswith(f"{path}: "):
            raise
        raise type(exc)(f"{path}: {exc}", parameter=exc.parameter) from exc
    except WavemeterError as exc:
        raise InputError(f"{path}: {exc}") from exc
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from exc


def _read(
    path: Path,
    request: ColumnRequest,
    need_x: bool,
    extras: tuple[bool, bool],
    allow_invalid: bool,
    max_bytes: int,
) -> Table:
    source = open_source(path, max_bytes)
    find_extras, find_temperature = extras
    roles = find_roles(
        source.shapes,
        source.unit_attributes,
        request,
        need_x=need_x,
        find_extras=find_extras,
        find_temperature=find_temperature,
    )
    singles = roles.singles()
    wanted = [role.name for role in singles.values()]
    wanted += [role.name for role in roles.ports] + list(request.keep)
    data = source.load(list(dict.fromkeys(wanted)), text_ok=set(request.keep))
    for name in request.keep:
        if data[name].ndim != 1:
            raise InputError(
                f"kept column {name!r} must be a vector, has shape {data[name].shape}",
                parameter="keep",
            )
    rows = _sample_count(source, data)
    if rows is None:
        first = roles.ports[0].name
        rows = _orient(data[first], first, None).shape[0]
    invalid = InvalidRows(rows)
    powers, port_names, port_units = _ports_array(roles.ports, data, rows, source, invalid)
    if powers.shape[1] < 3:
        raise InputError(
            f"found {powers.shape[1]} port column(s) ({', '.join(port_names)}); need at "
            "least 3: name them (ports)",
            parameter="ports",
        )
    fields: dict[str, object] = {}
    for key in ("x", "coarse"):
        if key in singles:
            role = singles[key]
            raw = data[role.name]
            invalid.add(~np.isfinite(raw), f"{role.name} is NaN, empty or inf")
            with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
                fields[f"{key}_hz"], unit = _axis_hz(role, raw, key)
            invalid.add(~np.isfinite(fields[f"{key}_hz"]), f"{role.name} is not a frequency")
            fields[f"{key}_column"] = role.name
            if key == "x":
                fields["x_unit"] = unit
    if "monitor" in singles:
        monitor = singles["monitor"]
        unit = _power_unit(monitor, source)
        monitor_w, reasons = _power_column(monitor.name, data[monitor.name], unit)
        problems = np.logical_or.reduce([mask for mask, _ in reasons])
        invalid.add(problems, f"{monitor.name} is NaN, inf, implausible or a 'no reading' code")
        with np.errstate(invalid="ignore"):
            invalid.add(~(monitor_w > 0), f"{monitor.name} is <= 0")
        fields["monitor_w"] = monitor_w
        fields["monitor_column"] = monitor.name
    if "temperature" in singles:
        temperature = singles["temperature"]
        raw = data[temperature.name]
        unit = temperature.unit or source.unit_attributes.get(temperature.name)
        if unit is None:
            raise InputError(
                f"temperature column {temperature.name!r} has no unit; name it like "
                "temperature_K or 'Temperature (C)'"
            )
        with np.errstate(over="ignore", invalid="ignore"):
            fields["temperature_k"] = temperature_to_k(raw, unit, temperature.name)
        invalid.add(
            ~np.isfinite(fields["temperature_k"]), f"{temperature.name} is NaN, empty or inf"
        )
        fields["temperature_column"] = temperature.name
    table = Table(
        source=path,
        powers_w=powers,
        port_names=port_names,
        port_units=port_units,
        invalid_code=invalid.code,
        invalid_reasons=tuple(invalid.reasons),
        row_index=np.arange(rows),
        rows_in_file=rows,
        row_label=source.row_label,
        kept={name: data[name] for name in request.keep},
        **fields,
    )
    if table.invalid.any() and not allow_invalid:
        raise InputError(
            f"{int(table.invalid.sum())} invalid row(s): {table.describe_invalid()}; fix or "
            "delete them, or allow invalid rows to skip them (allow_invalid)",
            parameter="allow_invalid",
        )
    return table


# ---------------------------------------------------------------------------- shapes
def _orient(array: np.ndarray, name: str, samples: int | None) -> np.ndarray:
    """A 2-D port array as (samples, ports): the axis whose length is ``samples``."""
    rows, cols = array.shape
    if samples is not None:
        if rows == samples and cols == samples:
            raise InputError(
                f"cannot tell samples from ports in {name!r} of shape {array.shape}: both axes "
                f"have {samples} entries"
            )
        if rows == samples:
            return array
        if cols == samples:
            return array.T
        raise InputError(
            f"{name!r} has shape {array.shape} but the other columns have {samples} samples"
        )
    if cols <= MAX_PORTS < rows:
        return array
    if rows <= MAX_PORTS < cols:
        return array.T
    raise InputError(
        f"cannot tell samples from ports in {name!r} of shape {array.shape}; store the "
        "frequency vector beside it or use more samples than ports"
    )


def _sample_count(source: Source, data: dict[str, np.ndarray]) -> int | None:
    """Samples N from the 1-D columns read (or, failing that, from all 1-D fields)."""
    lengths = {len(values) for values in data.values() if values.ndim == 1}
    if not lengths:
        lengths = {shape[0] for shape in source.shapes.values() if len(shape) == 1}
    if len(lengths) > 1:
        shown = ", ".join(f"{name!r} ({len(v)})" for name, v in data.items() if v.ndim == 1)
        raise InputError(f"columns have different lengths: {shown or sorted(lengths)}")
    return lengths.pop() if lengths else None


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


def _power_unit(role: Role, source: Source) -> str:
    unit = role.unit if role.unit is not None else source.unit_attributes.get(role.name)
    if unit is None:
        return ""
    try:
        return canonical_unit(unit, "power", f"column {role.name!r}")
    except InputError as exc:
        raise InputError(str(exc), parameter="power_unit") from exc


def _power_column(name: str, raw: np.ndarray, unit: str) -> tuple[np.ndarray, list[tuple]]:
    """Powers (W) from raw readings, and ``(mask, reason)`` for each kind of bad reading:
    NaN/inf, power-meter sentinels, dBm above :data:`MAX_DBM`, values that overflow."""
    nonfinite = ~np.isfinite(raw)
    with np.errstate(invalid="ignore"):
        sentinel = raw > SENTINEL_W
        implausible = np.zeros_like(nonfinite)
        if unit == "dBm":
            sentinel |= raw <= SENTINEL_DBM
            implausible = (raw > MAX_DBM) & ~sentinel
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


def _check_linear_column(name: str, raw: np.ndarray, unit: str) -> None:
    with np.errstate(invalid="ignore"):
        finite = raw[np.isfinite(raw) & (raw < SENTINEL_W)]
    if unit != "dBm" and finite.size and np.all(finite <= 0):
        raise InputError(
            f"column {name!r}{f' (labelled {unit})' if unit else ''} has no positive reading: "
            "are these dBm? give the power unit dBm (power_unit)",
            parameter="power_unit",
        )


def _ports_array(roles, data, samples, source, invalid: InvalidRows):
    """Port readings (N, n) in W with names and units; flags bad readings in ``invalid``."""
    columns, names, units = [], [], []
    for role in roles:
        values = data[role.name]
        unit = _power_unit(role, source)
        if values.ndim == 2:
            block = _orient(values, role.name, samples)
            leaf = role.name.rsplit("/", 1)[-1]
            base, unit_token = split_unit(leaf)[-1]
            if unit_token is not None and not known_unit(unit_token, "power"):
                base = leaf
            parts = [(f"{base}{k + 1}", block[:, k]) for k in range(block.shape[1])]
        else:
            parts = [(role.name, values)]
        for name, raw in parts:
            _check_linear_column(name, raw, unit)
            values, reasons = _power_column(name, raw, unit)
            for mask, reason in reasons:
                invalid.add(mask, reason)
            columns.append(values)
            names.append(name)
            units.append(unit)
    powers = np.column_stack(columns)
    with np.errstate(invalid="ignore", over="ignore"):
        invalid.add(~(powers.sum(axis=1) > 0), NO_LIGHT_REASON)
    return powers, tuple(names), tuple(units)


def _first(raw: np.ndarray, mask: np.ndarray) -> str:
    return f"{raw[mask][0]:g}" if mask.any() else ""
