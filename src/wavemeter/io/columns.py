"""Finding columns by name: the frequency axis, ports, monitor, temperature, coarse axis.

A column's role and unit come from its name: ``frequency_hz``, ``freq_THz``,
``Wavelength (nm)``, ``P1_mW``, ``port2_dBm``, ``Port 3 [uW]``, ``DC CH1``, ``p4``. What the
user names in a :class:`ColumnRequest` wins over what is found; anything left None is found
by name. Errors say which columns were seen and name the request field that resolves them
(``InputError.parameter``), never a command-line option.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass

from ..exceptions import InputError
from ..units import canonical_unit

__all__ = [
    "ColumnRequest",
    "Role",
    "Roles",
    "find_roles",
    "known_unit",
    "port_key",
    "split_unit",
    "WAVELENGTH_WORD",
]


@dataclass(frozen=True)
class ColumnRequest:
    r"""Which columns to use, their units, and how a text table's cells are written;
    ``None`` means find it from the file.

    Parameters
    ----------
    x : str, optional
        Column with the known frequency (sweep) or true frequency (test), or its wavelength.
    x_unit : str, optional
        Unit of ``x`` (Hz..THz, nm, um, m), overriding the unit in its name.
    ports : sequence of str, optional
        Port columns in order; a 2-D array counts as one port per row or column.
    power_unit : str, optional
        Unit of the port columns (W, mW, uW, nW, dBm, V), overriding their names.
    monitor : str, optional
        Source-power monitor column.
    temperature : str, optional
        Temperature column (K or C).
    coarse : str, optional
        Column with a coarse frequency (or wavelength) per reading, for calibration sets.
    keep : sequence of str
        Further columns to carry through unchanged (e.g. a time stamp).
    delimiter : str, optional
        The column delimiter of a text table (``","``, ``";"``, ``"\t"``, ``" "`` for runs
        of spaces and tabs, or another one character); default: an Excel ``sep=`` first
        line's, else sniffed. Refused for files of other formats.
    decimal : {".", ","}, optional
        The decimal mark of a text table; default ``"."``, or ``","`` for a
        ``;``-separated table written with decimal commas (noted). It cannot be the
        delimiter. Refused for files of other formats.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from wavemeter.io import ColumnRequest, read_table
    >>> path = Path(tempfile.mkdtemp()) / "scan.csv"
    >>> _ = path.write_text("Wavelength (nm),DC CH1,DC CH2,DC CH3,ref\n1550.0,0.5,0.25,0.25,9\n")
    >>> request = ColumnRequest(ports=["DC CH1", "DC CH2", "DC CH3"], power_unit="mW")
    >>> table = read_table(path, request)  # the ports named, their unit given
    >>> table.port_names, table.x_column, table.x_unit
    (('DC CH1', 'DC CH2', 'DC CH3'), 'Wavelength (nm)', 'nm')
    >>> print(f"{table.x_hz[0] / 1e12:.4f} THz", table.powers_w[0])
    193.4145 THz [0.0005  0.00025 0.00025]
    """

    x: str | None = None
    x_unit: str | None = None
    ports: Sequence[str] | None = None
    power_unit: str | None = None
    monitor: str | None = None
    temperature: str | None = None
    coarse: str | None = None
    keep: Sequence[str] = ()
    delimiter: str | None = None
    decimal: str | None = None


# ---------------------------------------------------------------------------- name patterns
def _normalise(text: str) -> str:
    return re.sub(r"[\s_\-]+", " ", text.strip().lower()).strip()


_BRACKETED = re.compile(r"^(.*?)\s*[\[({]\s*([^\])}]*?)\s*[\])}]\s*$")
_LAST_TOKEN = re.compile(r"^(.*?[^\s_\-])[\s_\-]+([^\s_\-]+)$")

_X_WORDS = r"freq|frequency|optical frequency|f|nu|ν|wavelength|wave length|lambda|λ|wl"
_X_ROLE = re.compile(
    rf"^(?:(?:true|truth|ref|reference|set|laser|source|known|nominal|target) )?(?:{_X_WORDS})$"
    r"|^truth$"
)
#: a word in an axis name that says it holds wavelengths, not frequencies
WAVELENGTH_WORD = re.compile(r"(wave|lambda|λ|wl)")
_PORT_FAMILY = r"p|port|ch|channel|pd|out|output|power|det|detector|photodiode|signal|sig"
_PORT_ROLE = re.compile(
    rf"^((?:(?:dc|ac|pd|det|detector|photodiode|optical) )?(?:{_PORT_FAMILY})) ?(\d+)$"
)
_PORT_MATRIX_ROLE = re.compile(
    r"^(?:p|power|powers|port|ports|port powers|pd|detector|detectors|signal|signals|"
    r"readings|channels|ch|dc|v|voltages|intensity|intensities)$"
)
_MONITOR_ROLE = re.compile(
    r"^(?:power monitor|monitor|mon|pm|monitor power|input power|source power|laser power|"
    r"tap|tap power|reference power|ref power)$"
)
_TEMPERATURE_ROLE = re.compile(r"^(?:(?:chip|stage|tec|device|sensor) )?(?:temperature|temp)$")


def split_unit(name: str) -> list[tuple[str, str | None]]:
    """Readings of a column name as ``(base, unit)``: the unit from a bracket or a suffix.

    ``"Wavelength (nm)"`` -> ``[("Wavelength", "nm")]``; ``"P1_mW"`` ->
    ``[("P1_mW", None), ("P1", "mW")]``; ``"DC CH1"`` -> ``[("DC CH1", None), ("DC", "CH1")]``.
    The caller keeps the reading whose base names a role; the unit is checked when used.

    Examples
    --------
    >>> from wavemeter.io import split_unit
    >>> split_unit("Wavelength (nm)")
    [('Wavelength', 'nm')]
    >>> split_unit("P1_mW")  # a suffix may be a unit or part of the name
    [('P1_mW', None), ('P1', 'mW')]
    """
    bracketed = _BRACKETED.match(name)
    if bracketed and bracketed.group(1):
        return [(bracketed.group(1), bracketed.group(2))]
    readings: list[tuple[str, str | None]] = [(name, None)]
    suffixed = _LAST_TOKEN.match(name.strip())
    if suffixed:
        readings.append((suffixed.group(1), suffixed.group(2)))
    return readings


def known_unit(unit: str | None, kind: str) -> str | None:
    """The canonical spelling of ``unit`` if it is a unit of ``kind``, else None."""
    if unit is None:
        return None
    try:
        return canonical_unit(unit, kind)
    except InputError:
        return None


def port_key(name: str) -> str:
    """A port column's identity without its unit: ``"Port 3 [uW]"`` and ``"port_3_mW"``
    both give ``"port3"``. Used to match a data file's ports to a calibration's.

    Examples
    --------
    >>> from wavemeter.io import port_key
    >>> port_key("Port 3 [uW]"), port_key("port_3_mW"), port_key("P1_W")
    ('port3', 'port3', 'p1')
    """
    base = name
    for reading_base, unit in split_unit(name):
        if unit is not None and (known_unit(unit, "power") or _BRACKETED.match(name)):
            base = reading_base
    return re.sub(r"[^0-9a-zµμ]", "", base.lower())


# ---------------------------------------------------------------------------- roles
@dataclass(frozen=True)
class Role:
    """A column chosen for a role: its name, the unit token in its name, a sort key."""

    name: str
    unit: str | None
    order: int = 0
    family: str = ""


@dataclass(frozen=True)
class Roles:
    """The columns a file's readings come from (None: the file has none for that role)."""

    x: Role | None
    ports: list[Role]
    monitor: Role | None
    temperature: Role | None
    coarse: Role | None

    def singles(self) -> dict[str, Role]:
        """The one-column roles that were found, by role name."""
        found = {
            "x": self.x,
            "monitor": self.monitor,
            "temperature": self.temperature,
            "coarse": self.coarse,
        }
        return {key: role for key, role in found.items() if role is not None}


def _match_role(name: str, pattern: re.Pattern) -> Role | None:
    leaf = name.rsplit("/", 1)[-1]
    for base, unit in split_unit(leaf):
        found = pattern.match(_normalise(base))
        if found:
            groups = found.groups()
            order = int(groups[1]) if len(groups) > 1 and groups[1] else 0
            family = _normalise(groups[0]) if groups else ""
            return Role(name, unit, order, family)
    return None


def _explicit_role(name: str, kind: str, unit_override: str | None) -> Role:
    """A column the user named: its unit from the override, a bracket or a known suffix."""
    if unit_override is not None:
        return Role(name, unit_override)
    leaf = name.rsplit("/", 1)[-1]
    for _, unit in reversed(split_unit(leaf)):
        if _BRACKETED.match(leaf) or known_unit(unit, kind):
            return Role(name, unit)
    return Role(name, None)


def _listed(names) -> str:
    return ", ".join(repr(name) for name in names) or "none"


def _single(candidates: list[Role], what: str, parameter: str) -> Role | None:
    if len(candidates) > 1:
        raise InputError(
            f"columns {_listed(role.name for role in candidates)} all look like the {what}; "
            f"name the one to use ({parameter})",
            parameter=parameter,
        )
    return candidates[0] if candidates else None


def _requested_columns(request: ColumnRequest):
    """``(request field, column name)`` of every column the request names."""
    yield "x", request.x
    yield "monitor", request.monitor
    yield "temperature", request.temperature
    yield "coarse", request.coarse
    for port in request.ports or ():
        yield "ports", port
    for kept in request.keep:
        yield "keep", kept


def _check_request(request: ColumnRequest, names: list[str]) -> None:
    for parameter in ("ports", "keep"):
        if isinstance(getattr(request, parameter), str):
            raise InputError(
                f"{parameter} must be a sequence of column names, not the text "
                f"{getattr(request, parameter)!r}",
                parameter=parameter,
            )
    for parameter, name in _requested_columns(request):
        if name is None:
            continue
        if not isinstance(name, str):
            raise InputError(
                f"column names are text; got {name!r} for {parameter}", parameter=parameter
            )
        if name not in names:
            raise InputError(
                f"no column {name!r} (given as {parameter}); columns: {_listed(names)}",
                parameter=parameter,
            )


def find_roles(
    shapes: dict[str, tuple[int, ...]],
    unit_attributes: dict[str, str],
    request: ColumnRequest,
    *,
    need_x: bool,
    find_extras: bool,
    find_temperature: bool | None = None,
) -> Roles:
    """Resolve every role to columns: the request first, else by name.

    Parameters
    ----------
    shapes : dict of str to tuple of int
        The file's numeric fields and their shapes (1-D columns, 2-D port arrays).
    unit_attributes : dict of str to str
        Units stored beside fields (HDF5 attributes): a temperature found by name counts
        only with a unit.
    request : ColumnRequest
        What the user chose.
    need_x : bool
        Whether a frequency or wavelength column must exist.
    find_extras : bool
        Whether to look for a monitor and a temperature column by name.
    find_temperature : bool, optional
        Whether to look for a temperature column by name; default ``find_extras``.

    Raises
    ------
    InputError
        For a named column the file lacks, an ambiguous or missing role; ``parameter``
        names the request field that resolves it.
    """
    names = list(shapes)
    _check_request(request, names)

    def one_dimensional(pattern):
        found = [_match_role(name, pattern) for name in names if len(shapes[name]) == 1]
        return [role for role in found if role is not None]

    x_role = None
    if request.x is not None:
        x_role = _explicit_role(request.x, "axis", request.x_unit)
    elif need_x:
        x_role = _single(one_dimensional(_X_ROLE), "frequency axis", "x")
        if x_role is not None and request.x_unit is not None:
            x_role = dataclasses.replace(x_role, unit=request.x_unit)
    if need_x and x_role is None:
        raise InputError(
            "no frequency or wavelength column (looked for names like frequency_hz, "
            f"freq_THz, wavelength_nm, 'Wavelength (nm)'); columns: {_listed(names)}; "
            "name the column like that, or give the axis column (x)",
            parameter="x",
        )
    monitor = temperature = None
    if request.monitor is not None:
        monitor = _explicit_role(request.monitor, "power", None)
    elif find_extras:
        monitor = _single(one_dimensional(_MONITOR_ROLE), "power monitor", "monitor")
    if monitor is not None and monitor.unit is None and request.power_unit is not None:
        monitor = dataclasses.replace(monitor, unit=request.power_unit)
    if request.temperature is not None:
        temperature = _explicit_role(request.temperature, "temperature", None)
    elif find_extras if find_temperature is None else find_temperature:
        found = _single(one_dimensional(_TEMPERATURE_ROLE), "temperature", "temperature")
        has_unit = found is not None and (found.unit or unit_attributes.get(found.name))
        temperature = found if has_unit else None
    coarse = None if request.coarse is None else _explicit_role(request.coarse, "axis", None)
    return Roles(x_role, _find_ports(shapes, request), monitor, temperature, coarse)


def _find_ports(shapes: dict[str, tuple[int, ...]], request: ColumnRequest) -> list[Role]:
    names = list(shapes)
    if request.ports is not None:
        roles = [_explicit_role(name, "power", request.power_unit) for name in request.ports]
        if len(set(request.ports)) != len(request.ports):
            raise InputError(
                f"the port columns given name a column twice: {_listed(request.ports)}",
                parameter="ports",
            )
    else:
        singles = [
            role
            for role in (_match_role(name, _PORT_ROLE) for name in names)
            if role is not None and len(shapes[role.name]) == 1
        ]
        roles = sorted(singles, key=lambda role: role.order)
        numbers = [(role.family, role.order) for role in roles]
        if len(set(numbers)) != len(numbers):
            raise InputError(
                f"port columns {_listed(role.name for role in roles)} repeat a port number; "
                "name the port columns to use, in order (ports)",
                parameter="ports",
            )
        if not roles:
            matrices = [
                role
                for role in (_match_role(name, _PORT_MATRIX_ROLE) for name in names)
                if role is not None and len(shapes[role.name]) == 2
            ]
            roles = [m for m in [_single(matrices, "port array", "ports")] if m is not None]
        if request.power_unit is not None:
            roles = [dataclasses.replace(role, unit=request.power_unit) for role in roles]
    if not roles:
        raise InputError(
            "no port columns (looked for names like P1_mW, port2_dBm, 'Port 3 [uW]', "
            f"'DC CH1', p4); columns: {_listed(names)}; name them like that, or give the "
            "port columns in order (ports)",
            parameter="ports",
        )
    return roles
