"""Reading a whole table of readings: open the file, find the columns, convert to SI.

:func:`read_table` opens a file by its format (:func:`~wavemeter.io.formats.open_source`),
plans its columns (:mod:`~wavemeter.io.plan`), reads the fields, converts the rows
(:mod:`~wavemeter.io.convert`) and makes the whole-column checks (:mod:`~wavemeter.io.checks`).
Invalid rows are flagged with their reason and file line; they are an error unless the
caller allows them. Every error names the file (:func:`about_file`, which chunked reading
shares), and what the reader chose that the caller did not say is noted
(:class:`~wavemeter.exceptions.InputNote`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import warnings
from pathlib import Path

from ..exceptions import InputError, InputNote, WavemeterError
from .checks import ColumnChecks
from .columns import ColumnRequest
from .convert import convert_rows
from .formats import open_source
from .plan import complete_plan, find_fields
from .source import MAX_BYTES, STDIN, Source
from .table import Table

__all__ = ["read_table", "invalid_rows_error", "about_file", "open_noted"]


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
    r"""Read readings from a data file, find the columns by name and convert to SI.

    Parameters
    ----------
    path : str or Path
        CSV/TSV (header row; delimiter and decimal mark found, or as ``request`` says),
        HDF5, MAT (v5 or v7.3), NPZ or Parquet; ``"-"`` reads standard input. A pipe or
        device is read once.
    request : ColumnRequest, optional
        Columns, units and a text table's delimiter and decimal mark chosen by the user;
        anything left None is found.
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

    Warns
    -----
    InputNote
        When the reader chose what ``request`` did not say: a ``;``-separated file read
        with decimal commas.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from wavemeter.io import read_table
    >>> path = Path(tempfile.mkdtemp()) / "sweep.csv"
    >>> rows = ["freq_THz,P1_mW,P2_mW,P3_mW", "193.40,0.5,0.25,0.25", "193.41,0.25,0.5,0.25"]
    >>> _ = path.write_text("\n".join(rows) + "\n")
    >>> table = read_table(path)  # columns found by name, units from the names, values in SI
    >>> print(table.x_unit, table.x_hz, table.port_units)
    THz [1.9340e+14 1.9341e+14] ('mW', 'mW', 'mW')
    >>> print(table.powers_w)  # W
    [[0.0005  0.00025 0.00025]
     [0.00025 0.0005  0.00025]]
    """
    path = Path(path)
    request = request or ColumnRequest()
    extras = (find_extras, find_extras if find_temperature is None else find_temperature)
    with about_file(path):
        return _read(path, request, need_x, extras, allow_invalid, max_bytes)


@contextlib.contextmanager
def about_file(path: Path):
    """Errors of reading a file start with its name; every error is an InputError (or a
    FileFormatError)."""
    try:
        yield
    except InputError as exc:
        if str(exc).startswith(f"{path}: "):
            raise
        raise type(exc)(f"{path}: {exc}", parameter=exc.parameter) from exc
    except WavemeterError as exc:
        raise InputError(f"{path}: {exc}") from exc
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from exc


def open_noted(path, max_bytes: int, request: ColumnRequest, label: Path, depth: int) -> Source:
    """The file opened by its format with the request's delimiter and decimal mark; what
    its reader chose that the request did not say is noted (:class:`InputNote`, warned
    ``depth`` frames up), the file named ``label`` (``<stdin>`` for standard input)."""
    source = open_source(path, max_bytes, request.delimiter, request.decimal)
    if source.note is not None:
        name = "<stdin>" if str(label) == STDIN else label
        warnings.warn(InputNote(f"{name}: {source.note}"), stacklevel=depth + 1)
    return source


def _read(
    path: Path,
    request: ColumnRequest,
    need_x: bool,
    extras: tuple[bool, bool],
    allow_invalid: bool,
    max_bytes: int,
) -> Table:
    source = open_noted(path, max_bytes, request, path, depth=4)
    roles, fields = find_fields(source, request, need_x, extras)
    data = source.load(fields, text_ok=set(request.keep))
    shapes = {name: data[name].shape for name in fields}
    plan = dataclasses.replace(complete_plan(source, request, roles, fields, shapes), path=path)
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
