"""What to read from a file and how: the columns, their units and the ports, decided once.

:func:`plan_columns` finds the roles of a file's fields by name (or as the user chose them),
their units and the ports (a 2-D port field gives one port per row or column) from its
header or metadata, before any value is read; whole-file reading, chunked reading and a
stream's header share it. A field whose length a text file does not declare is planned
once it is read (:func:`complete_plan` with the shapes read).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..exceptions import InputError
from ..units import canonical_unit
from .columns import ColumnRequest, Role, find_roles, known_unit, split_unit
from .source import Source

__all__ = ["ColumnPlan", "plan_columns", "find_fields", "complete_plan", "MAX_PORTS"]

#: the most ports a 2-D port array may have; the other axis holds the samples
MAX_PORTS = 64


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
    roles, fields = find_fields(source, request, need_x, extras)
    return complete_plan(source, request, roles, fields, source.shapes)


def find_fields(source: Source, request: ColumnRequest, need_x: bool, extras):
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


def complete_plan(source, request, roles, fields, shapes) -> ColumnPlan:
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


def _power_unit(role: Role, source: Source) -> str:
    unit = role.unit if role.unit is not None else source.unit_attributes.get(role.name)
    if unit is None:
        return ""
    try:
        return canonical_unit(unit, "power", f"column {role.name!r}")
    except InputError as exc:
        raise InputError(str(exc), parameter="power_unit") from exc
