"""The numbers a stream's data lines hold, line by line or a block of lines at once."""

from __future__ import annotations

import csv
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .stream_header import StreamHeader

__all__ = ["LineReader"]


class LineReader:
    """The numbers a data line holds, by the header's rules.

    A line must have as many cells as the header (a trailing delimiter aside); every field
    the plan reads is a number (with the stream's decimal mark), an empty cell NaN. What the
    numbers mean (units, invalid values) is :func:`~wavemeter.io.convert.convert_rows`'
    business.

    Parameters
    ----------
    header : StreamHeader
        The stream's header.

    Examples
    --------
    >>> from pathlib import Path
    >>> from wavemeter.jobs import read_header
    >>> lines = ["# the meter's log", "frequency_hz,p1_mW,p2_mW,p3_mW", "1,0.5,0.25,0.25"]
    >>> numbered = iter(enumerate(lines, start=1))
    >>> header = read_header(numbered, Path("<stdin>"), None, find_temperature=False)
    >>> from wavemeter.jobs import LineReader
    >>> reader = LineReader(header)
    >>> reader.values(lines[2])  # the numbers by field, as read (units come later)
    ({'p1_mW': 0.5, 'p2_mW': 0.25, 'p3_mW': 0.25}, None)
    >>> reader.values("1,0.5,0.25")  # a line that is no reading, and why
    (None, '3 cells, the header has 4')
    """

    def __init__(self, header: StreamHeader):
        self.cells = header.cells
        self.width = len(header.names)
        self.fields = [(name, header.names.index(name)) for name in header.plan.fields]

    def _split(self, line: str) -> list[str]:
        """The cells of a line; raises csv.Error for one that cannot be split."""
        delimiter = self.cells.delimiter
        if delimiter is not None and '"' not in line and "\r" not in line and "\x00" not in line:
            # no quoting, nothing the CSV reader refuses: the cells it would find, faster
            return line.split(delimiter)
        return self.cells.split(line)

    def values(self, line: str) -> tuple[dict[str, float] | None, str | None]:
        """The plan's fields of a data line (no newline) by name, or None and why not."""
        try:
            cells = self._split(line)
        except csv.Error as exc:
            return None, f"cannot be split into cells ({exc})"
        if len(cells) == self.width + 1 and not cells[-1].strip():
            cells.pop()  # a trailing delimiter
        if len(cells) != self.width:
            return None, f"{len(cells)} cells, the header has {self.width}"
        data = {}
        number = self.cells.number
        for name, column in self.fields:
            cell = cells[column].strip()
            try:
                data[name] = number(cell)
            except ValueError:
                return None, f"column {name!r}: {cell[:40]!r} is not a number"
        return data, None

    def block(self, lines: list[str]) -> tuple[dict[str, np.ndarray], list[str | None]]:
        """The plan's fields of many data lines (no newlines) as arrays, NaN where a line
        holds no reading, and why each line holds none (None where it does): what
        :meth:`values` gives line by line, found at once when every line is plain (no
        quoting, as many cells as the header, a number with a decimal point in every cell
        read)."""
        width, delimiter = self.width, self.cells.delimiter
        if delimiter is not None and self.cells.decimal == ".":
            text = delimiter.join(lines)
            if (
                '"' not in text
                and "\r" not in text
                and "\x00" not in text
                and all(line.count(delimiter) == width - 1 for line in lines)
            ):
                cells = text.split(delimiter)
                try:
                    data = {
                        name: np.array(list(map(float, cells[column::width])))
                        for name, column in self.fields
                    }
                except ValueError:  # an empty cell, or text: line by line, with the reasons
                    pass
                else:
                    return data, [None] * len(lines)
        data = {name: np.full(len(lines), np.nan) for name, _ in self.fields}
        reasons = []
        for row, line in enumerate(lines):
            values, reason = self.values(line)
            reasons.append(reason)
            for name, value in (values or {}).items():
                data[name][row] = value
        return data, reasons
