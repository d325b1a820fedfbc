"""Reading a calibration's sweep files whole, its dark readings, and what was read.

:func:`read_sweeps` reads one or more sweep files (``"-"``: standard input, named
``<stdin>``) into memory, valid rows only, concatenated in the order given, and checks that
they agree (the same ports, a power monitor in all or none); a calibrator that needs the
chip temperature of each reading gets it from each file's temperature column or from one
temperature per file. :func:`read_dark_w` gives the per-port dark readings from values or
a file of readings with the source off (averaged). :class:`SweepRead` is what reading one
file found, :class:`SweepsRead` what reading all of them found; :func:`sweep_metadata` is
what a calibration file keeps of them. Reading a sweep in chunks is
:mod:`wavemeter.jobs.chunks`.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import InputError, WavemeterError
from ..io import ColumnRequest, port_key, read_table
from ..io.convert import NO_LIGHT_REASON
from .readings import TEMPERATURE_COLUMN_NAMES

__all__ = [
    "STDIN_LABEL",
    "SweepRead",
    "Sweeps",
    "SweepsRead",
    "input_label",
    "invalid_examples",
    "read_dark_w",
    "read_sweeps",
    "stdin_named",
    "sweep_metadata",
    "value_range",
]

#: how standard input (``"-"``) is named in messages and metadata
STDIN_LABEL = "<stdin>"
#: invalid rows a record keeps as examples
EXAMPLES = 5


def input_label(path) -> str:
    """An input as messages name it: ``<stdin>`` for ``-``, else the path as given."""
    return STDIN_LABEL if str(path) == "-" else str(path)


@contextlib.contextmanager
def stdin_named(path):
    """Errors about standard input (``-``) name it ``<stdin>``."""
    try:
        yield
    except WavemeterError as exc:
        prefix = f"{path}: "
        if str(path) != "-" or not str(exc).startswith(prefix):
            raise
        renamed = type(exc)(f"{STDIN_LABEL}: {str(exc)[len(prefix) :]}")
        renamed.parameter = getattr(exc, "parameter", None)
        raise renamed from exc


def value_range(values) -> list[float] | None:
    """``[lowest, highest]`` of some values; None for None or none."""
    if values is None or np.size(values) == 0:
        return None
    return [float(np.min(values)), float(np.max(values))]


def invalid_examples(table, limit: int = EXAMPLES) -> tuple[str, ...]:
    """The first invalid rows of a table with their reasons, ``line 5 (P2_mW is NaN)``."""
    rows = np.flatnonzero(table.invalid)[:limit]
    return tuple(
        f"{table.row_label(int(table.row_index[k]))} "
        f"({table.invalid_reasons[table.invalid_code[k]]})"
        for k in rows
    )


@dataclass(frozen=True)
class SweepRead:
    """What reading a sweep file found, for the calibration's metadata and messages.

    Attributes
    ----------
    source : Path
        The file (as named to the user; ``<stdin>`` for standard input).
    x_column, x_unit : str or None
        The frequency or wavelength column and its unit.
    port_names, port_units : tuple of str
        The port columns and their units.
    monitor_column, temperature_column : str or None
        The power monitor's and the chip temperature's columns.
    n_rows : int
        Valid rows, the readings calibrated on.
    dropped_rows : int
        Rows skipped as invalid.
    invalid_examples : tuple of str
        The first skipped rows with their reasons, ``line 5 (P2_mW is NaN)``.
    temperature_range_k : list of float or None
        Lowest and highest chip temperature of the valid rows (K), with a temperature column.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> from wavemeter.jobs import CalibrateOptions, calibrate_file
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> path = Path(tempfile.mkdtemp()) / "sweep.csv"
    >>> write_table(path, {"wavelength_nm": 299792458e9 / f_hz,
    ...                    **{f"p{k + 1}_mW": 1e3 * powers[:, k] for k in range(3)}})
    >>> read = calibrate_file(path, options=CalibrateOptions(fsr_hz=50e9)).read
    >>> record = read.records[0]
    >>> record.x_column, record.x_unit, record.port_units, record.n_rows, record.dropped_rows
    ('wavelength_nm', 'nm', ('mW', 'mW', 'mW'), 200, 0)
    """

    source: Path
    x_column: str | None
    x_unit: str | None
    port_names: tuple[str, ...]
    port_units: tuple[str, ...]
    monitor_column: str | None
    temperature_column: str | None
    n_rows: int
    dropped_rows: int
    invalid_examples: tuple[str, ...] = ()
    temperature_range_k: list[float] | None = None

    @classmethod
    def of_table(cls, table, valid) -> SweepRead:
        """The record of a file read whole: ``table`` as read, ``valid`` its valid rows."""
        return cls(
            source=valid.source,
            x_column=valid.x_column,
            x_unit=valid.x_unit,
            port_names=tuple(valid.port_names),
            port_units=tuple(valid.port_units),
            monitor_column=valid.monitor_column,
            temperature_column=valid.temperature_column,
            n_rows=valid.n_rows,
            dropped_rows=valid.dropped_rows,
            invalid_examples=invalid_examples(table),
            temperature_range_k=value_range(valid.temperature_k),
        )


@dataclass(frozen=True)
class SweepsRead:
    """What reading the sweep files of one calibration found.

    Attributes
    ----------
    records : tuple of SweepRead
        One per file, in the order given.
    temperature_range_k : list of float or None
        Lowest and highest chip temperature (K): of every reading for a calibrator that
        needs it, else of the files' temperature columns when every file has one.
    given_k : tuple of float
        The chip temperature given for each file (K); empty when it came from columns.
    temperature_from : str or None
        Where the temperature of a calibrator that needs it came from: ``"temperature_k"``
        (given) or the columns' names; None for a calibrator that needs none.
    dark : SweepRead or None
        What reading the dark readings' file found (no axis), when there was one.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> from wavemeter.jobs import CalibrateOptions, calibrate_file
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> path = Path(tempfile.mkdtemp()) / "sweep.csv"
    >>> write_table(path, {"wavelength_nm": 299792458e9 / f_hz,
    ...                    **{f"p{k + 1}_mW": 1e3 * powers[:, k] for k in range(3)}})
    >>> read = calibrate_file(path, options=CalibrateOptions(fsr_hz=50e9)).read
    >>> len(read.records), read.temperature_from, read.dark  # one file, no temperature, no dark
    (1, None, None)
    """

    records: tuple[SweepRead, ...]
    temperature_range_k: list[float] | None = None
    given_k: tuple[float, ...] = ()
    temperature_from: str | None = None
    dark: SweepRead | None = None

    @property
    def first(self) -> SweepRead:
        return self.records[0]

    @property
    def label(self) -> str:
        """The files, as messages name them."""
        return ", ".join(str(record.source) for record in self.records)

    @property
    def n_rows(self) -> int:
        return sum(record.n_rows for record in self.records)


@dataclass(frozen=True, eq=False)
class Sweeps:
    """The valid readings of one calibration's sweep files, read whole and concatenated.

    Attributes
    ----------
    powers_w : ndarray, shape (N, n)
        Port readings (W, or the unit of the files).
    x_hz : ndarray, shape (N,)
        Known frequency of each reading (Hz).
    monitor_w, temperature_k : ndarray, shape (N,), or None
        Power monitor (W) and, for a calibrator that needs it, chip temperature (K).
    read : SweepsRead
        What was read.
    """

    powers_w: np.ndarray
    x_hz: np.ndarray
    monitor_w: np.ndarray | None
    temperature_k: np.ndarray | None
    read: SweepsRead


def _port_list(table) -> str:
    return ", ".join(table.port_names)


def _busy(progress: Callable | None, description: str):
    """``progress(description, None, "")``: a task of unknown length (a spinner)."""
    return progress(description, None, "") if progress else contextlib.nullcontext()


def _read(path, request, *, drop_invalid: bool, find_temperature, progress, light=True):
    """One file read whole (``light=False``: readings with the source off, whose rows may
    sum to zero or less)."""
    label = input_label(path)
    with _busy(progress, f"reading {label}"), stdin_named(path):
        table = read_table(
            path,
            request,
            need_x=light,
            find_extras=light,
            allow_invalid=drop_invalid or not light,
            find_temperature=find_temperature,
        )
    table = dataclasses.replace(table, source=Path(label))
    if not light:  # no light is what dark readings are
        no_light = [
            k for k, reason in enumerate(table.invalid_reasons) if reason == NO_LIGHT_REASON
        ]
        dark_rows = np.isin(table.invalid_code, no_light)
        table = dataclasses.replace(table, invalid_code=np.where(dark_rows, -1, table.invalid_code))
        if table.invalid.any() and not drop_invalid:
            raise InputError(
                f"{table.source}: {int(table.invalid.sum())} invalid row(s): "
                f"{table.describe_invalid()}; fix or delete them, or allow invalid rows to "
                "skip them (allow_invalid)",
                parameter="allow_invalid",
            )
    return table


def _check_same_layout(tables, explicit_ports: bool) -> None:
    """Every sweep file has the first one's ports (names, unless chosen) and monitor."""
    first = tables[0]
    names = [port_key(name) for name in first.port_names]
    for table in tables[1:]:
        if len(table.port_names) != len(names) or (
            not explicit_ports and [port_key(name) for name in table.port_names] != names
        ):
            raise InputError(
                f"{table.source} has ports {_port_list(table)} but {first.source} has "
                f"{_port_list(first)}; the sweeps of one calibration need the same ports: "
                "choose the port columns of every file, in order (ports)",
                parameter="ports",
            )
        if (table.monitor_w is None) != (first.monitor_w is None):
            having, lacking = (table, first) if first.monitor_w is None else (first, table)
            raise InputError(
                f"{having.source} has a power monitor ({having.monitor_column}) and "
                f"{lacking.source} has none; the sweeps of one calibration need a monitor in "
                "every file or in none",
                parameter="monitor",
            )


def read_sweeps(
    paths, options, *, temperature: bool, method_label: str, progress: Callable | None = None
) -> Sweeps:
    """Read every sweep file whole, check that they agree, and find each row's temperature.

    Parameters
    ----------
    paths : sequence of str or Path
        The sweep files, in order.
    options : CalibrateOptions
        Their columns (``request``), ``drop_invalid``, the temperature of each file
        (``temperature_k``).
    temperature : bool
        The calibrator needs the chip temperature of each reading.
    method_label : str
        The calibrator's method, for messages.
    progress : callable, optional
        As :func:`wavemeter.jobs.calibrate_file` takes it.

    Raises
    ------
    InputError
        What reading refuses; files that disagree; a file without the temperature a
        calibrator needs.
    """
    request = options.request or ColumnRequest()
    given = tuple(float(value) for value in options.temperature_k)
    tables = []
    for path in paths:
        table = _read(
            path,
            request,
            drop_invalid=options.drop_invalid,
            find_temperature=None if not temperature else not given,
            progress=progress,
        )
        tables.append((table, table.valid_only()))
    valid = [table for _, table in tables]
    _check_same_layout(valid, request.ports is not None)
    temperature_k, source = None, None
    if temperature and given:
        temperature_k = np.concatenate(
            [np.full(table.n_rows, value) for table, value in zip(valid, given, strict=True)]
        )
        source = "temperature_k"
    elif temperature:
        for table in valid:
            if table.temperature_k is None:
                raise InputError(
                    f"a {method_label} calibration needs the chip temperature of each reading, "
                    f"and {table.source} has no temperature column (looked for "
                    f"{TEMPERATURE_COLUMN_NAMES}); name it (temperature), or give one "
                    "temperature per sweep file, in file order (temperature_k)",
                    parameter="temperature_k",
                )
        temperature_k = np.concatenate([table.temperature_k for table in valid])
        source = ", ".join(dict.fromkeys(table.temperature_column for table in valid))
    records = tuple(SweepRead.of_table(whole, table) for whole, table in tables)
    extent = value_range(temperature_k)
    if temperature_k is None:
        ranges = [record.temperature_range_k for record in records]
        if all(ranges):
            extent = [min(low for low, _ in ranges), max(high for _, high in ranges)]
    monitor = valid[0].monitor_w is not None
    return Sweeps(
        powers_w=np.concatenate([table.powers_w for table in valid]),
        x_hz=np.concatenate([table.x_hz for table in valid]),
        monitor_w=np.concatenate([table.monitor_w for table in valid]) if monitor else None,
        temperature_k=temperature_k,
        read=SweepsRead(records, extent, given, source),
    )


def read_dark_w(options, layout, *, progress: Callable | None = None):
    """Per-port dark readings (W) from ``options.dark_w`` or the mean of the readings in
    ``options.dark_file``, checked against the sweep's ports.

    Parameters
    ----------
    options : CalibrateOptions
        ``dark_w`` or ``dark_file``; the columns (``request``: ports and power unit) and
        ``drop_invalid`` for the file.
    layout
        The sweep as read: ``source`` and ``port_names``.

    Returns
    -------
    dark_w : ndarray, shape (n,), or None
        None without values or a file.
    record : SweepRead or None
        What reading the file found (rows skipped), with a file.

    Raises
    ------
    InputError
        Another number of values or ports than the sweep's; a file without valid readings.
    """
    ports = len(layout.port_names)
    expected = f"{layout.source} has {ports} ports ({_port_list(layout)})"
    if options.dark_w is not None:
        if len(options.dark_w) != ports:
            raise InputError(
                f"dark_w gives {len(options.dark_w)} value(s) but {expected}; give one offset "
                "per port, in that order",
                parameter="dark_w",
            )
        return np.array(options.dark_w, dtype=float), None
    if options.dark_file is None:
        return None, None
    request = options.request or ColumnRequest()
    ports_only = ColumnRequest(
        ports=request.ports,
        power_unit=request.power_unit,
        delimiter=request.delimiter,
        decimal=request.decimal,
    )
    whole = _read(
        options.dark_file,
        ports_only,
        drop_invalid=options.drop_invalid,
        find_temperature=False,
        progress=progress,
        light=False,
    )
    dark = whole.valid_only()
    names = [port_key(name) for name in dark.port_names]
    if len(names) != ports or (
        request.ports is None and names != [port_key(name) for name in layout.port_names]
    ):
        raise InputError(
            f"{dark.source} has ports {_port_list(dark)} but {expected}; the dark readings "
            "need the sweep's ports: choose the port columns of both files, in order (ports)",
            parameter="ports",
        )
    if dark.n_rows == 0:
        raise InputError(f"{dark.source}: no valid dark readings to average", parameter="dark_file")
    return dark.powers_w.mean(axis=0), SweepRead.of_table(whole, dark)


def _one_or_list(values: list):
    """The value every file shares, or the list of each file's."""
    return values[0] if all(value == values[0] for value in values) else values


def sweep_metadata(read: SweepsRead, dark_file=None) -> dict:
    """What a calibration file keeps of its sweeps (JSON-ready). One sweep file: its name
    and columns; several: the list of names, and each column entry a list where the files
    differ. ``dark_file``: the dark readings' file, when there was one."""
    records = read.records
    several = len(records) > 1
    metadata = {
        "sweep_file": [str(r.source) for r in records] if several else str(read.first.source),
        "x_column": _one_or_list([r.x_column for r in records]),
        "x_unit": _one_or_list([r.x_unit for r in records]),
        "port_columns": _one_or_list([list(r.port_names) for r in records]),
        "port_units": _one_or_list([list(r.port_units) for r in records]),
        "monitor_column": _one_or_list([r.monitor_column for r in records]),
        "temperature_column": None
        if read.given_k
        else _one_or_list([r.temperature_column for r in records]),
        "temperature_k_range": read.temperature_range_k,
        "rows": read.n_rows,
        "dropped_rows": sum(r.dropped_rows for r in records),
    }
    if several:
        metadata["rows_per_file"] = [r.n_rows for r in records]
    if read.given_k:
        metadata["temperature_k_given"] = list(read.given_k)
    if dark_file is not None:
        metadata["dark_file"] = input_label(dark_file)
    return metadata
