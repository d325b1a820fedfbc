"""Reading CSV, TSV and whitespace-separated text tables: one parser each, whole or in chunks.

Three parsers, each written once: pyarrow's CSV reader when it is installed, numpy's C
reader, and an exact cell-by-cell parse that names the file line of a bad cell. A whole
read (``Source.load``) is one chunk: pyarrow is fed the whole file, else numpy all its
lines, else the exact parse. A chunked read (``Source.chunks``) feeds the same parsers
pieces: pyarrow blocks of whole lines, cut into chunks of exact row counts; when a block
does not parse, the lines from the first row not yet given are read in batches, numpy
first and, where it fails, exactly. Every data row must have as many fields as the header
(one more when it is empty: a trailing delimiter), which catches decimal commas in
comma-separated files; a last line without a newline whose last value is shorter than the
column's other values is refused as probably truncated. The layout (delimiter, decimal
mark, header) is found by :mod:`~wavemeter.io.text_layout`.
"""

from __future__ import annotations

import csv
import functools
import io
import itertools
import re
import sys
import warnings
from collections.abc import Callable, Iterator

import numpy as np

from ..exceptions import FileFormatError
from .source import Chunk, RawInput, Source
from .text_layout import (
    TextLayout,
    check_not_truncated,
    is_number,
    parse_number,
    sniff_layout,
    split_cells,
)

__all__ = ["read_text"]

#: bytes of a text file parsed by pyarrow at a time in a chunked read (its default block
#: size): larger blocks are not faster
_BLOCK_BYTES = 1 << 20


def read_text(raw: RawInput, max_bytes: int, delimiter=None, decimal=None) -> Source:
    """The columns of a delimited text table, each a 1-D field of yet unknown length.

    A field allowed to be text (``text_ok``) comes back from ``load`` as numbers when
    every cell is one, else as text; from ``chunks`` always as text (cells stripped), for
    the caller to turn into numbers by the file's decimal mark (``Source.decimal``).

    Parameters
    ----------
    raw : RawInput
        The file.
    max_bytes : int
        The largest text file read whole (its values take up to a few times its size);
        a chunked read holds only one chunk and has no file size limit.
    delimiter : str, optional
        The column delimiter (``" "``: runs of spaces and tabs); default: sniffed.
    decimal : {".", ","}, optional
        The decimal mark; default: found (see :func:`~wavemeter.io.text_layout.sniff_layout`).
    """
    layout = sniff_layout(raw, delimiter, decimal)
    line_numbers = functools.cache(lambda: [number for number, _ in _data_lines(raw, layout)])

    def row_label(row: int) -> str:
        numbers = line_numbers()
        return f"line {numbers[row]}" if row < len(numbers) else f"data row {row + 1}"

    def load(names, text_ok=frozenset()):
        if raw.size > max_bytes:
            raise FileFormatError(
                f"the file holds {raw.size} bytes, more than the {max_bytes}-byte size limit "
                "for a text table read whole: split it, or raise the limit (max_bytes)",
                parameter="max_bytes",
            )
        [chunk] = _chunks(raw, layout, list(names), None, set(text_ok), row_label)
        return chunk.columns

    def chunks(names, chunk_rows, sample_axes=None, text_ok=frozenset()):
        return _chunks(raw, layout, list(names), chunk_rows, set(text_ok), row_label)

    return Source(
        {name: (-1,) for name in layout.names},
        load,
        row_label,
        chunks=chunks,
        count_rows=lambda: _count_rows(raw, layout),
        decimal=layout.decimal,
        note=layout.note,
    )


def _chunks(raw, layout, names, chunk_rows, text_ok, row_label) -> Iterator[Chunk]:
    """Chunks of at most ``chunk_rows`` rows of the columns ``names``, in file order; the
    whole file as one chunk when ``chunk_rows`` is None (then a column in ``text_ok`` is
    numbers when every cell is one, and rows are named by ``row_label``)."""
    done = 0
    finder = row_label if chunk_rows is None else _LineFinder(raw, layout)
    try:
        for chunk in _arrow_chunks(raw, layout, names, chunk_rows, text_ok, finder):
            done = chunk.start + chunk.n_rows
            yield chunk
    except _ArrowFailed:
        yield from _line_chunks(raw, layout, names, chunk_rows, text_ok, done, row_label)
        return
    if done == 0:
        raise FileFormatError("the file has a header row but no data rows")
    check_not_truncated(raw, layout, lambda: finder(done - 1))


# ---------------------------------------------------------------------------- lines
def _text_lines(raw: RawInput, encoding: str) -> io.TextIOWrapper:
    """The input as text lines ended by LF, CRLF or CR (each kept at the line's end)."""
    return io.TextIOWrapper(raw.open(), encoding=encoding, errors="replace", newline="")


def _data_lines(raw: RawInput, layout: TextLayout):
    """``(line_number, text)`` of each non-blank data line, line numbers 1-based."""
    with _text_lines(raw, layout.encoding) as handle:
        for number, line in enumerate(handle, start=1):
            if number > layout.header_line + 1 and line.strip():
                yield number, line


class _LineFinder:
    """The file line of data row ``i`` (zero-based, blank lines not counted), found by
    reading the file forward from the last row asked for (rows are asked for in order)."""

    def __init__(self, raw: RawInput, layout: TextLayout):
        self._raw = raw
        self._layout = layout
        self._lines = None
        self._row = -1
        self._number = 0

    def __call__(self, row: int) -> str:
        if self._lines is None or row < self._row:
            self._lines = _data_lines(self._raw, self._layout)
            self._row, self._number = -1, 0
        while self._row < row:
            found = next(self._lines, None)
            if found is None:
                return f"data row {row + 1}"
            self._number = found[0]
            self._row += 1
        return f"line {self._number}"


def _count_rows(raw: RawInput, layout: TextLayout) -> int:
    """The data rows of the file, for progress: its line ends after the header, counted a
    block at a time without parsing (about as fast as the file is read), and a last line
    without one. Exact unless the file holds blank lines after the header: each counts."""
    if layout.data_offset is None:  # a header longer than the first bytes read
        return sum(1 for _ in _data_lines(raw, layout))
    newline = b"\n" if b"\n" in raw.head(layout.data_offset + _BLOCK_BYTES) else b"\r"
    ends, unended = 0, False  # line ends; text after the last one
    with raw.open() as handle:
        handle.seek(layout.data_offset)
        for block in iter(lambda: handle.read(_BLOCK_BYTES), b""):
            count = block.count(newline)
            ends += count
            after = block.rsplit(newline, 1)[-1] if count else block
            unended = bool(after.strip()) or (unended and not count)
    return ends + unended


# ---------------------------------------------------------------------------- pyarrow
class _ArrowFailed(Exception):
    """pyarrow is missing or cannot parse a piece: the lines from the first row not yet
    given are read by the line parsers, which name what is wrong."""


def _pyarrow():
    """``(pyarrow, pyarrow.csv)``, or None when pyarrow is not installed."""
    try:
        import pyarrow
        import pyarrow.csv
    except ImportError:
        return None
    return pyarrow, pyarrow.csv


def _arrow_chunks(raw, layout, names, chunk_rows, text_ok, finder) -> Iterator[Chunk]:
    """Chunks parsed by pyarrow's CSV reader: the whole file at once (``chunk_rows``
    None), else one block of whole lines at a time (not its streaming reader, which reads
    tens of MB ahead). Raises :class:`_ArrowFailed` when pyarrow is missing, the file is
    whitespace-delimited, or a piece does not parse, after the chunks before it."""
    modules = _pyarrow()
    if layout.delimiter is None or layout.data_offset is None or modules is None:
        raise _ArrowFailed
    pa, pa_csv = modules
    whole = chunk_rows is None
    text = set() if whole else text_ok
    options = {
        "read_options": pa_csv.ReadOptions(column_names=layout.names, use_threads=whole),
        "parse_options": pa_csv.ParseOptions(delimiter=layout.delimiter),
        "convert_options": pa_csv.ConvertOptions(
            include_columns=names,
            column_types={name: pa.string() if name in text else pa.float64() for name in names},
            null_values=[""],  # only empty cells: "N/A" is an error, as with numpy
            decimal_point=layout.decimal,
        ),
    }
    limit = sys.maxsize if whole else chunk_rows
    pending: list = []  # parsed tables not yet given out
    pending_rows = 0
    start = 0
    with raw.open() as handle:
        handle.seek(layout.data_offset)
        pieces = [handle, None] if whole else _line_blocks(handle)
        for piece in pieces:
            if piece is not None:
                try:
                    table = pa_csv.read_csv(piece if whole else pa.py_buffer(piece), **options)
                except pa.ArrowException:
                    raise _ArrowFailed from None
                pending.append(table)
                pending_rows += table.num_rows
            while pending_rows >= limit or (piece is None and pending_rows):
                table = pa.concat_tables(pending)
                size = min(limit, pending_rows)
                columns = {
                    name: _arrow_column(table.column(name)[:size], name in text) for name in names
                }
                rest = table.slice(size)
                pending, pending_rows = [rest], rest.num_rows
                yield Chunk(start, columns, finder)
                start += size


def _line_blocks(handle):
    """Blocks of about :data:`_BLOCK_BYTES` of whole lines (cut after a line end; blank
    blocks left out); a last None marks the end."""
    rest = b""
    while True:
        data = handle.read(_BLOCK_BYTES)
        if not data:
            if rest.strip():
                yield rest
            yield None
            return
        data = rest + data
        cut = max(data.rfind(b"\n"), data.rfind(b"\r")) + 1
        block, rest = data[:cut], data[cut:]
        if block.strip():
            yield block


def _arrow_column(column, text: bool) -> np.ndarray:
    """A parsed column as float64 (nulls NaN) or, for a text column, stripped text."""
    if text:
        return np.char.strip(np.asarray(column.to_pylist(), dtype=str))
    return column.to_numpy()


# ---------------------------------------------------------------------------- numpy, exact
def _line_chunks(raw, layout, names, chunk_rows, text_ok, skip, row_label) -> Iterator[Chunk]:
    """Chunks of data lines from data row ``skip`` on, each piece parsed by numpy or, when
    it does not parse, exactly (naming the line of a bad cell): the whole file as one piece
    when ``chunk_rows`` is None, else batches of ``chunk_rows`` lines."""
    whole = chunk_rows is None
    text = set() if whole else text_ok
    columns = [layout.names.index(name) for name in names]
    for start, piece, last in _line_pieces(raw, layout, chunk_rows, skip):
        data = None if text else _parse_with_numpy(piece.lines(), layout, columns)
        if data is None:
            arrays, numbers = _parse_exactly(piece.numbered(), layout, names, text_ok, whole)
            labels = row_label if whole else _chunk_labels(start, numbers)
        else:
            arrays = {name: data[:, k] for k, name in enumerate(names)}
            labels = row_label if whole else _chunk_labels(start, piece.numbers())
        if last:
            final = start + len(next(iter(arrays.values()))) - 1
            check_not_truncated(raw, layout, functools.partial(labels, final))
        yield Chunk(start, arrays, labels)


class _Batch:
    """Data lines held in memory: ``(line_number, text)`` each."""

    def __init__(self, numbered: list):
        self._numbered = numbered

    def lines(self):
        return [line for _, line in self._numbered]

    def numbered(self):
        return self._numbered

    def numbers(self) -> list[int]:
        return [number for number, _ in self._numbered]


class _WholeFile:
    """Every data line of the file, read from it each time they are asked for."""

    def __init__(self, raw: RawInput, layout: TextLayout):
        self._raw = raw
        self._layout = layout

    def lines(self):
        handle = _text_lines(self._raw, self._layout.encoding)
        return _closing(itertools.islice(handle, self._layout.header_line + 1, None), handle)

    def numbered(self):
        return _data_lines(self._raw, self._layout)


def _closing(lines, handle):
    with handle:
        yield from lines


def _line_pieces(raw, layout, chunk_rows, skip: int):
    """``(start, piece, last)``: the pieces of the data lines from data row ``skip`` on."""
    if chunk_rows is None:
        yield 0, _WholeFile(raw, layout), True
        return
    lines = itertools.islice(_data_lines(raw, layout), skip, None)
    batch = list(itertools.islice(lines, chunk_rows))
    if not batch:
        raise FileFormatError("the file has a header row but no data rows")
    start = skip
    while batch:
        following = list(itertools.islice(lines, chunk_rows))
        yield start, _Batch(batch), not following
        start += len(batch)
        batch = following


def _chunk_labels(start: int, numbers: list[int]) -> Callable[[int], str]:
    return lambda row: f"line {numbers[row - start]}"


def _parse_with_numpy(lines, layout: TextLayout, columns: list[int]):
    """Columns (m, k) of data lines parsed by numpy's C reader; None when any line does not
    parse, has another number of fields than the header, or there are none (the exact
    parser then says what is wrong)."""
    if layout.decimal == ",":  # points for commas; a point (no number then) for an "x"
        lines = (line.replace(".", "x").replace(",", ".") for line in lines)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            data = np.loadtxt(
                lines,
                delimiter=layout.delimiter,
                comments=None,
                quotechar='"',
                ndmin=2,
            )
    except ValueError:
        return None
    if data.shape[0] == 0 or data.shape[1] != len(layout.names):
        return None
    return data[:, columns]


def _fields(line: str, number: int, layout: TextLayout) -> list[str]:
    """The fields of a data line, checked against the header's number of columns."""
    try:
        fields = split_cells(line.rstrip("\r\n"), layout.delimiter)
    except csv.Error as exc:
        raise FileFormatError(f"line {number} cannot be split into fields ({exc})") from None
    width = len(layout.names)
    if len(fields) == width + 1 and not fields[-1].strip():
        fields = fields[:-1]  # a trailing delimiter
    if len(fields) != width:
        hint = ""
        if len(fields) > width and layout.delimiter == "," and re.search(r"\d,\d", line):
            hint = " (decimal commas in a comma-separated file? write decimal points)"
        raise FileFormatError(
            f"line {number} has {len(fields)} fields, the header has {width}{hint}; every "
            "row must have one value per column"
        )
    return fields


def _parse_exactly(numbered, layout, names, text_ok, numbers_if_all):
    """Data lines parsed cell by cell: empty cells become NaN; a column in ``text_ok`` is
    text (with ``numbers_if_all``: numbers when every cell is one); any other cell that is
    not a number is an error. Returns the columns and the lines' numbers."""
    columns = [layout.names.index(name) for name in names]
    cells: list[list[str]] = [[] for _ in names]
    line_numbers = []
    ends_with_newline = True
    for number, line in numbered:
        fields = _fields(line, number, layout)
        line_numbers.append(number)
        ends_with_newline = line.endswith(("\n", "\r"))
        for k, column in enumerate(columns):
            cells[k].append(fields[column].strip())
    if not line_numbers:
        raise FileFormatError("the file has a header row but no data rows")
    cut = None if ends_with_newline else line_numbers[-1]
    arrays = {}
    for name, values in zip(names, cells, strict=True):
        if name in text_ok and not numbers_if_all:
            arrays[name] = np.array(values, dtype=str)
        else:
            arrays[name] = _numbers(name, values, name in text_ok, line_numbers, cut, layout)
    return arrays, line_numbers


def _numbers(name, cells, text_ok, line_numbers, cut_line, layout) -> np.ndarray:
    """A column of cells as float64 (empty cells NaN), or as text when allowed."""
    values = np.empty(len(cells))
    for row, cell in enumerate(cells):
        try:
            values[row] = parse_number(cell, layout.decimal)
        except ValueError:
            if text_ok:
                return np.array(cells, dtype=str)
            hint, parameter = _number_hint(cell, line_numbers[row] == cut_line, layout.decimal)
            raise FileFormatError(
                f"line {line_numbers[row]}, column {name!r}: {cell[:40]!r} is not a number{hint}",
                parameter=parameter,
            ) from None
    return values


def _number_hint(cell: str, last_cut: bool, decimal: str) -> tuple[str, str | None]:
    """Why a cell may not be a number, and the parameter that helps."""
    if decimal == "." and re.fullmatch(r"[-+]?\d+,\d+", cell):
        return " (a decimal comma? write decimal points, or give the decimal mark ',')", "decimal"
    if decimal == "," and is_number(cell, "."):
        hint = " (a decimal point in a file read with decimal commas? give the decimal mark '.')"
        return hint, "decimal"
    if last_cut:
        return " (the last line has no newline: is the file truncated?)", None
    return "", None
