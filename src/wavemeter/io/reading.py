"""Reading a table of readings: open the file by its format, find the columns, convert to SI.

Invalid rows (NaN or inf, power-meter "no reading" codes, dBm readings above
:data:`MAX_DBM`, no light, a bad monitor reading) are flagged with their reason and file
line; they are an error unless the caller allows them. Every error names the file.

Whole-file reading (:func:`read_table`) and chunked reading
(:func:`wavemeter.io.iter_readings`) share the same steps: :func:`plan_columns` finds the
columns, their units and the ports once from the file's header or metadata;
:func:`convert_rows` turns any run of consecutive rows into a :class:`Table` in SI units
with its invalid rows flagged; :class:`ColumnChecks` makes the checks that need a whole
column, one chunk at a time.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import InputError, WavemeterError
from ..units import (
    FREQUENCY_UNITS,
    SENTINEL_DBM,
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

__all__ = [
    "read_table",
    "plan_columns",
    "convert_rows",
    "PlainRowConverter",
    "ColumnPlan",
    "ColumnChecks",
    "invalid_rows_error",
    "SENTINEL_W",
    "SENTINEL_DBM",
    "MAX_DBM",
    "MAX_PORTS",
    "NO_LIGHT_REASON",
]

#: raw readings above this (any linear unit) are instrument "no reading" codes (9.91e37)
SENTINEL_W = 1e20
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
    roles, fields = _roles_and_fields(source, request, need_x, extras)
    data = source.load(fields, text_ok=set(request.keep))
    shapes = {name: data[name].shape for name in fields}
    plan = dataclasses.replace(_complete_plan(source, request, roles, fields, shapes), path=path)
    for name, axis in plan.sample_axes.items():
        if axis == 1:
            data[name] = data[name].T
    checks = ColumnChecks()
    table = convert_rows(plan, data, 0, source.row_label, checks)
    checks.finish()
    if table.invalid.any() and not allow_invalid:
        raise invalid_rows_error(int(table.invalid.sum()), table.describe_invalid())
    return table


def invalid_rows_error(count: int, described: str) -> InputError:
    """The error for invalid rows not allowed: how many, the first with their reasons."""
    return InputError(
        f"{count} invalid row(s): {described}; fix or delete them, or allow invalid rows to "
        "skip them (allow_invalid)",
        parameter="allow_invalid",
    )


# ---------------------------------------------------------------------------- plan
@dataclass(frozen=True)
class ColumnPlan:
    """What to read from a file and how to convert it, decided once from its header or
    metadata, before any value is read; shared by whole-file and chunked reading.

    Attributes
    ----------
    path : Path
        The file, named in messages.
    request : ColumnRequest
        The user's choices.
    singles : dict of str to Role
        The one-column roles found (``"x"``, ``"monitor"``, ``"temperature"``,
        ``"coarse"``).
    ports : list of Role
        The port columns (a 2-D field is one role).
    role_units : tuple of str
        The power unit of each port role (``""``: relative).
    port_names, port_units : tuple of str
        The name and unit of each port, a 2-D field giving ``P1, P2, ...``.
    fields : list of str
        The fields to read, each once.
    sample_axes : dict of str to int
        For each 2-D port field, the axis that runs over the samples.
    monitor_unit, temperature_unit : str or None
        Units of the monitor and temperature columns.
    """

    path: Path
    request: ColumnRequest
    singles: dict[str, Role]
    ports: list[Role]
    role_units: tuple[str, ...]
    port_names: tuple[str, ...]
    port_units: tuple[str, ...]
    fields: list[str]
    sample_axes: dict[str, int]
    monitor_unit: str | None = None
    temperature_unit: str | None = None


def plan_columns(
    source: Source, request: ColumnRequest, *, need_x: bool, extras: tuple[bool, bool]
) -> ColumnPlan:
    """Find the columns and their units from a source's field names and shapes.

    Parameters
    ----------
    source : Source
        The opened file.
    request : ColumnRequest
        The user's choices.
    need_x : bool
        Whether a frequency/wavelength column must exist.
    extras : tuple of (bool, bool)
        Whether to look for a monitor, and a temperature column, by name.

    Raises
    ------
    InputError
        For missing, ambiguous or duplicate columns, unknown units, a kept field that is
        not a vector, fewer than 3 ports, fields of different lengths.
    """
    roles, fields = _roles_and_fields(source, request, need_x, extras)
    return _complete_plan(source, request, roles, fields, source.shapes)


def _roles_and_fields(source: Source, request: ColumnRequest, need_x: bool, extras):
    """The roles found and the fields to read for them, each once."""
    find_extras, find_temperature = extras
    roles = find_roles(
        source.shapes,
        source.unit_attributes,
        request,
        need_x=need_x,
        find_extras=find_extras,
        find_temperature=find_temperature,
    )
    wanted = [role.name for role in roles.singles().values()]
    wanted += [role.name for role in roles.ports] + list(request.keep)
    return roles, list(dict.fromkeys(wanted))


def _complete_plan(source, request, roles, fields, shapes) -> ColumnPlan:
    """The plan from the roles and the shapes of the fields (declared, or as read)."""
    singles = roles.singles()
    for name in request.keep:
        if len(shapes[name]) != 1:
            raise InputError(
                f"kept column {name!r} must be a vector, has shape {shapes[name]}",
                parameter="keep",
            )
    known = {name: shapes[name] for name in fields if shapes[name] != (-1,)}
    samples = _declared_samples(source, known)
    sample_axes: dict[str, int] = {}
    role_units = tuple(_power_unit(role, source) for role in roles.ports)
    port_names: list[str] = []
    port_units: list[str] = []
    for role, unit in zip(roles.ports, role_units, strict=True):
        shape = shapes[role.name]
        if len(shape) == 2:
            sample_axes[role.name] = axis = _sample_axis(shape, role.name, samples)
            leaf = role.name.rsplit("/", 1)[-1]
            base, unit_token = split_unit(leaf)[-1]
            if unit_token is not None and not known_unit(unit_token, "power"):
                base = leaf
            port_names += [f"{base}{k + 1}" for k in range(shape[1 - axis])]
            port_units += [unit] * shape[1 - axis]
        else:
            port_names.append(role.name)
            port_units.append(unit)
    if len(port_names) < 3:
        raise InputError(
            f"found {len(port_names)} port column(s) ({', '.join(port_names)}); need at "
            "least 3: name them (ports)",
            parameter="ports",
        )
    units = {}
    if "monitor" in singles:
        units["monitor_unit"] = _power_unit(singles["monitor"], source)
    if "temperature" in singles:
        temperature = singles["temperature"]
        unit = temperature.unit or source.unit_attributes.get(temperature.name)
        if unit is None:
            raise InputError(
                f"temperature column {temperature.name!r} has no unit; name it like "
                "temperature_K or 'Temperature (C)'"
            )
        units["temperature_unit"] = unit
    return ColumnPlan(
        path=Path(),
        request=request,
        singles=singles,
        ports=list(roles.ports),
        role_units=role_units,
        port_names=tuple(port_names),
        port_units=tuple(port_units),
        fields=fields,
        sample_axes=sample_axes,
        **units,
    )


def _declared_samples(source: Source, known: dict[str, tuple[int, ...]]) -> int | None:
    """Samples N from the declared lengths of the 1-D fields read (or, failing that, of
    all 1-D fields); None when only 2-D fields or text columns (length yet unknown)."""
    lengths = {shape[0] for shape in known.values() if len(shape) == 1}
    if not lengths and not known:
        return None
    if not lengths:
        lengths = {shape[0] for shape in source.shapes.values() if len(shape) == 1}
    if len(lengths) > 1:
        shown = ", ".join(
            f"{name!r} ({shape[0]})" for name, shape in known.items() if len(shape) == 1
        )
        raise InputError(f"columns have different lengths: {shown or sorted(lengths)}")
    return lengths.pop() if lengths else None


# ---------------------------------------------------------------------------- conversion
class ColumnChecks:
    """Checks that need every row of a column, made chunk by chunk: each port column must
    have a positive reading somewhere (else its values are probably dBm), and an axis
    without a unit keeps the unit its first finite values chose.
    """

    def __init__(self):
        self._seen: dict[str, tuple[bool, bool]] = {}  # port -> (finite seen, positive seen)
        self._units: dict[str, str] = {}
        self._port_units: dict[str, str] = {}

    def port(self, name: str, raw: np.ndarray, unit: str) -> None:
        """Note a chunk of a port column's raw readings."""
        with np.errstate(invalid="ignore"):
            finite = raw[np.isfinite(raw) & (raw < SENTINEL_W)]
        seen_finite, seen_positive = self._seen.get(name, (False, False))
        self._seen[name] = (
            seen_finite or finite.size > 0,
            seen_positive or bool(np.any(finite > 0)),
        )
        self._port_units[name] = unit

    def axis_unit(self, key: str) -> str | None:
        """The unit an axis without one was read in so far (None: none chosen yet)."""
        return self._units.get(key)

    def choose_axis_unit(self, key: str, unit: str) -> None:
        """Keep ``unit`` for the axis ``key`` from now on."""
        self._units.setdefault(key, unit)

    def finish(self) -> None:
        """Raise for a port column that had no positive reading in any row."""
        for name, (seen_finite, seen_positive) in self._seen.items():
            unit = self._port_units[name]
            if unit != "dBm" and seen_finite and not seen_positive:
                raise InputError(
                    f"column {name!r}{f' (labelled {unit})' if unit else ''} has no positive "
                    "reading: are these dBm? give the power unit dBm (power_unit)",
                    parameter="power_unit",
                )


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
    live readout's one row at a time. This applies its rules (:func:`_raw_power_problems`,
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
            if any(mask.any() for mask in _raw_power_problems(raw, unit)):
                return None
            with np.errstate(over="ignore"):
                powers_w[members] = power_to_w(raw, unit or "W", names[0])
        if not np.isfinite(powers_w).all() or _no_light(powers_w):
            return None
        if self._temperature is None:
            return powers_w, None
        kelvin = float(_temperature_k(self._plan, np.array([values[self._temperature.name]]))[0])
        return (powers_w, kelvin) if math.isfinite(kelvin) else None


# ---------------------------------------------------------------------------- shapes
def _sample_axis(shape: tuple[int, int], name: str, samples: int | None) -> int:
    """The axis of a 2-D port array that runs over the samples (0 or 1)."""
    rows, cols = shape
    if samples is not None:
        if rows == samples and cols == samples:
            raise InputError(
                f"cannot tell samples from ports in {name!r} of shape {shape}: both axes "
                f"have {samples} entries"
            )
        if rows == samples:
            return 0
        if cols == samples:
            return 1
        raise InputError(f"{name!r} has shape {shape} but the other columns have {samples} samples")
    if cols <= MAX_PORTS < rows:
        return 0
    if rows <= MAX_PORTS < cols:
        return 1
    raise InputError(
        f"cannot tell samples from ports in {name!r} of shape {shape}; store the "
        "frequency vector beside it or use more samples than ports"
    )


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


def _raw_power_problems(raw: np.ndarray, unit: str | None) -> tuple[np.ndarray, ...]:
    """Masks of the raw power readings that are no reading: NaN/inf, power-meter
    sentinels, dBm above :data:`MAX_DBM`."""
    nonfinite = ~np.isfinite(raw)
    with np.errstate(invalid="ignore"):
        sentinel = raw > SENTINEL_W
        implausible = np.zeros_like(nonfinite)
        if unit == "dBm":
            sentinel |= raw <= SENTINEL_DBM
            implausible = (raw > MAX_DBM) & ~sentinel
    return nonfinite, sentinel, implausible


def _no_light(powers_w: np.ndarray) -> np.ndarray:
    """Readings (..., n) whose ports do not sum to more than zero (NaN included)."""
    with np.errstate(invalid="ignore", over="ignore"):
        return ~(powers_w.sum(axis=-1) > 0)


def _power_column(name: str, raw: np.ndarray, unit: str) -> tuple[np.ndarray, list[tuple]]:
    """Powers (W) from raw readings, and ``(mask, reason)`` for each kind of bad reading:
    NaN/inf, power-meter sentinels, dBm above :data:`MAX_DBM`, values that overflow."""
    nonfinite, sentinel, implausible = _raw_power_problems(raw, unit)
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
            checks.port(name, raw, unit)
            values_w, reasons = _power_column(name, raw, unit)
            for mask, reason in reasons:
                invalid.add(mask, reason)
            columns.append(values_w)
    powers = np.column_stack(columns) if rows else np.empty((0, len(columns)))
    invalid.add(_no_light(powers), NO_LIGHT_REASON)
    return powers


def _first(raw: np.ndarray, mask: np.ndarray) -> str:
    return f"{raw[mask][0]:g}" if mask.any() else ""
