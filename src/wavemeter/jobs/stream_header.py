"""A stream's header: the first line that names the columns of a live readout, found as in
files, and what it tells about reading each line after it."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

from ..exceptions import InputError
from ..io import ColumnRequest
from ..io.plan import ColumnPlan, plan_columns
from ..io.source import Source
from ..io.text_layout import LineCells, column_names, excel_separator

__all__ = ["StreamHeader", "read_header"]


@dataclass(frozen=True)
class StreamHeader:
    """The columns a stream's header line gives, found as in files.

    Attributes
    ----------
    source : Path
        What the input is called in messages (``<stdin>``, a file name).
    line : int
        The header's line number (1-based).
    names : tuple of str
        Every column of the header, in order.
    delimiter : str or None
        The delimiter (None: runs of whitespace).
    port_names, port_units : tuple of str
        The port columns and the unit each is read in (``""``: relative).
    temperature_column, coarse_column : str or None
        The columns found for these roles.
    plan : ColumnPlan
        What to read from each line and how to convert it.
    cells : LineCells
        How a line is split into cells and a cell read as a number.

    Examples
    --------
    >>> from pathlib import Path
    >>> from wavemeter.jobs import read_header
    >>> lines = ["# the meter's log", "frequency_hz,p1_mW,p2_mW,p3_mW", "1,0.5,0.25,0.25"]
    >>> numbered = iter(enumerate(lines, start=1))
    >>> header = read_header(numbered, Path("<stdin>"), None, find_temperature=False)
    >>> header.source.name, header.names
    ('<stdin>', ('frequency_hz', 'p1_mW', 'p2_mW', 'p3_mW'))
    """

    source: Path
    line: int
    names: tuple[str, ...]
    delimiter: str | None
    port_names: tuple[str, ...]
    port_units: tuple[str, ...]
    temperature_column: str | None
    coarse_column: str | None
    plan: ColumnPlan
    cells: LineCells


def read_header(numbered, source: Path, request, find_temperature: bool) -> StreamHeader:
    """The first line that is not blank or a comment, its columns found as in files (an
    Excel ``sep=`` first line names the delimiter).

    Parameters
    ----------
    numbered : iterator of (int, str)
        Line numbers (1-based) and lines; consumed up to the header line.
    source : Path
        What the input is called in messages.
    request : ColumnRequest or None
        Columns chosen by the user (and the delimiter and decimal mark).
    find_temperature : bool
        Look for a temperature column by name.

    Returns
    -------
    StreamHeader

    Raises
    ------
    InputError
        When the lines end before a header, or its columns cannot be found as in files.

    Examples
    --------
    >>> from pathlib import Path
    >>> from wavemeter.jobs import read_header
    >>> lines = ["# the meter's log", "frequency_hz,p1_mW,p2_mW,p3_mW", "1,0.5,0.25,0.25"]
    >>> numbered = iter(enumerate(lines, start=1))
    >>> header = read_header(numbered, Path("<stdin>"), None, find_temperature=False)
    >>> header.line, header.delimiter, header.port_names, header.port_units
    (2, ',', ('p1_mW', 'p2_mW', 'p3_mW'), ('mW', 'mW', 'mW'))
    >>> next(numbered)  # the header consumed; the data lines follow
    (3, '1,0.5,0.25,0.25')
    """
    request = request or ColumnRequest()
    declared = None
    for number, text in numbered:
        line = text.lstrip("\ufeff").strip()
        if number == 1 and (declared := excel_separator(text)) is not None:
            continue
        if not line or line.startswith("#"):
            continue
        delimiter = request.delimiter if request.delimiter is not None else declared
        cells = LineCells(line, delimiter, request.decimal, str(source))
        try:
            names = column_names(cells.split(line))
        except csv.Error as exc:
            raise InputError(
                f"line {number}: the header cannot be split into names ({exc})"
            ) from None
        # the header's columns as a text file's: of unknown length, values line by line
        columns = Source({column: (-1,) for column in names}, load=None)
        plan = plan_columns(columns, request, need_x=False, extras=(False, find_temperature))
        singles = plan.singles
        return StreamHeader(
            source=source,
            line=number,
            names=tuple(names),
            delimiter=cells.delimiter,
            port_names=plan.port_names,
            port_units=plan.port_units,
            temperature_column=singles["temperature"].name if "temperature" in singles else None,
            coarse_column=singles["coarse"].name if "coarse" in singles else None,
            plan=plan,
            cells=cells,
        )
    raise InputError(
        "no header line: the input ended before a line naming the columns (e.g. P1_mW,P2_mW,P3_mW)"
    )
