"""CSV, TSV and whitespace-separated text tables: reading and writing.

Reading sniffs the delimiter (tab, comma, semicolon, runs of spaces) from the header row,
skips ``#`` comment lines and blank lines before it, and parses with pyarrow's CSV reader
when it is installed, numpy's otherwise, falling back to an exact line-by-line parse that
names the file line of any bad cell. Every data row must have as many fields as the header
(one more is allowed when it is empty: a trailing delimiter), which also catches decimal
commas in comma-separated files. A last line without a newline whose last value is shorter
than the column's other values is refused as probably truncated. Writing produces the
shortest text that reads back to the same float64, and prefixes text cells a spreadsheet
would run as a formula with ``'`` (the OWASP convention).
"""

from __future__ import annotations

import csv
import functools
import io
import itertools
import re
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import FileFormatError
from .source import Chunk, RawInput, Source

__all__ = ["read_text", "write_csv", "write_tsv", "refuse_text_chunk", "DelimitedChunkWriter"]

_HEAD_BYTES = 1 << 16
_TAIL_BYTES = 1 << 16
_WRITE_CHUNK_ROWS = 1 << 13  # rows turned into text at a time: bounds the strings held
_DELIMITERS = ("\t", ",", ";", None)  # None: runs of whitespace; ties go to the first
_LINE_END = re.compile(r"\r\n|\n|\r")  # as Python's universal newlines: LF, CRLF, CR
_LINE_END_BYTES = re.compile(rb"\r\n|\n|\r")


# ---------------------------------------------------------------------------- layout
@dataclass(frozen=True)
class _TextLayout:
    encoding: str
    delimiter: str | None  # None: runs of whitespace
    names: list[str]
    header_line: int  # zero-based line index of the header
    data_offset: int | None  # byte offset of the first data line (None: not found)


def refuse_text_chunk(head: bytes, chunk: bytes) -> str | None:
    """Why a chunk of a text stream cannot be a table (None when it can)."""
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "is UTF-16 text: save it as UTF-8 or ASCII"
    if b"\x00" in chunk:
        return "holds NUL bytes: it is not a text table (a binary file of an unknown format?)"
    return None


def _decode(head: bytes) -> tuple[str, str]:
    try:
        return head.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError as exc:
        if exc.start >= len(head) - 3:  # a multi-byte character cut by the read size
            return head[: exc.start].decode("utf-8-sig"), "utf-8"
        return head.decode("latin-1"), "latin-1"


def split_cells(line: str, delimiter: str | None) -> list[str]:
    """The cells of one text line: CSV quoting with ``delimiter``, or whitespace when None."""
    if delimiter is None:
        return [cell.strip('"') for cell in line.split()]
    return next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])


def _sniff_layout(raw: RawInput) -> _TextLayout:
    head = raw.head(_HEAD_BYTES + 1)
    complete = len(head) <= _HEAD_BYTES
    head = head[:_HEAD_BYTES]
    if not head.strip():
        raise FileFormatError("the file is empty")
    refused = refuse_text_chunk(head, head)
    if refused:
        raise FileFormatError(refused)
    text, encoding = _decode(head)
    lines = _LINE_END.split(text)
    if not complete:
        lines = lines[:-1]  # the last line may be cut by the read size
    header_line = next(
        (i for i, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")),
        None,
    )
    if header_line is None:
        raise FileFormatError("no header row: the file holds only comments or blank lines")
    sample = [line for line in lines[header_line + 1 : header_line + 6] if line.strip()]
    if not sample:
        raise FileFormatError("the file has a header row but no data rows")
    header = lines[header_line]
    candidates = []  # (rows agreeing with the header, priority, delimiter, names)
    for priority, delimiter in enumerate(_DELIMITERS):
        names = split_cells(header, delimiter)
        if len(names) >= 2:
            widths = (len(split_cells(line, delimiter)) for line in sample)
            agreeing = sum(width in (len(names), len(names) + 1) for width in widths)
            candidates.append((agreeing, -priority, delimiter, names))
    if not candidates:
        raise FileFormatError(
            "cannot tell the column delimiter (tried tab, comma, semicolon, spaces): the "
            "header row has a single column"
        )
    _, _, delimiter, names = max(candidates, key=lambda candidate: candidate[:2])
    ends = [end.end() for end in itertools.islice(_LINE_END_BYTES.finditer(head), header_line + 1)]
    data_offset = ends[header_line] if len(ends) > header_line else None
    return _TextLayout(encoding, delimiter, column_names(names), header_line, data_offset)


def column_names(raw: list[str]) -> list[str]:
    """Header cells as column names (unquoted, ``column k`` for an empty one); a duplicate
    name raises FileFormatError naming both columns."""
    names = [name.strip().strip('"').strip() or f"column {k + 1}" for k, name in enumerate(raw)]
    seen: dict[str, int] = {}
    for k, name in enumerate(names):
        if name in seen:
            raise FileFormatError(
                f"duplicate column name {name!r} (columns {seen[name] + 1} and {k + 1}); "
                "rename one of them"
            )
        seen[name] = k
    return names


# ---------------------------------------------------------------------------- reading
def read_text(raw: RawInput, max_bytes: int) -> Source:
    """The columns of a delimited text table, each a 1-D field of yet unknown length.

    Whole fields (``load``) are read by pyarrow's CSV reader, else numpy's, else the exact
    line parser. Chunks (``chunks``) are read by pyarrow's CSV reader a block of whole
    lines at a time (cut into chunks of exact row counts), else by lines, each chunk parsed
    by numpy, else exactly; when a block does not parse, the rest of the file is read by
    lines, so that a bad cell is named by its line as in a whole read. A field allowed to
    be text (``text_ok``) comes back from ``chunks`` as text always (cells stripped), for
    the caller to turn into numbers when every cell is one. The progress of a chunked read
    is counted in bytes of the file.

    Parameters
    ----------
    raw : RawInput
        The file.
    max_bytes : int
        The largest text file read whole (its values take up to a few times its size);
        a chunked read holds only one chunk and has no file size limit.
    """
    layout = _sniff_layout(raw)

    def chunks(names, chunk_rows, sample_axes=None, text_ok=frozenset()):
        return _stream_text(raw, layout, list(names), chunk_rows, set(text_ok))

    if raw.size > max_bytes:

        def refuse(names, text_ok=frozenset()):
            raise FileFormatError(
                f"the file holds {raw.size} bytes, more than the {max_bytes}-byte size limit "
                "for a text table read whole: split it, or raise the limit (max_bytes)",
                parameter="max_bytes",
            )

        return Source(
            {name: (-1,) for name in layout.names},
            refuse,
            chunks=chunks,
            progress_total=(raw.size, "bytes"),
        )
    line_numbers = functools.cache(lambda: _data_line_numbers(raw, layout))

    def load(names, text_ok=frozenset()):
        columns = [layout.names.index(name) for name in names]
        data = _parse_text_with_arrow(raw, layout, columns)
        if data is None:
            data = _parse_text_with_numpy(raw, layout, columns)
        if data is None:
            return _parse_text_exactly(raw, layout, names, set(text_ok))
        if data.shape[0] == 0:
            raise FileFormatError("the file has a header row but no data rows")
        _check_not_truncated(raw, layout, lambda: row_label(data.shape[0] - 1))
        return {name: data[:, k] for k, name in enumerate(names)}

    def row_label(row: int) -> str:
        numbers = line_numbers()
        return f"line {numbers[row]}" if row < len(numbers) else f"data row {row + 1}"

    return Source(
        {name: (-1,) for name in layout.names},
        load,
        row_label,
        chunks=chunks,
        progress_total=(raw.size, "bytes"),
    )


def _parse_text_with_arrow(raw: RawInput, layout: _TextLayout, columns: list[int]):
    """Columns (N, k) parsed by pyarrow when it is installed (about 8x faster than numpy).

    Returns None when pyarrow is missing, the file is whitespace-delimited, or pyarrow
    cannot parse it (a bad cell, a row with another number of fields); the other parsers
    then read the file and report what is wrong.
    """
    if layout.delimiter is None or layout.data_offset is None:
        return None
    try:
        import pyarrow as pa
        import pyarrow.csv as pa_csv
    except ImportError:
        return None
    names = [layout.names[k] for k in columns]
    try:
        with raw.open() as handle:
            handle.seek(layout.data_offset)
            table = pa_csv.read_csv(
                handle,
                read_options=pa_csv.ReadOptions(column_names=layout.names),
                parse_options=pa_csv.ParseOptions(delimiter=layout.delimiter),
                convert_options=pa_csv.ConvertOptions(
                    include_columns=names,
                    column_types=dict.fromkeys(names, pa.float64()),
                    null_values=[""],  # only empty cells: "N/A" is an error, as with numpy
                ),
            )
    except pa.ArrowException:
        return None
    if table.num_rows == 0:
        return None
    return np.column_stack([table.column(name).to_numpy() for name in names])


def _parse_text_with_numpy(raw: RawInput, layout: _TextLayout, columns: list[int]):
    """Columns (N, k) parsed by numpy's C reader; None when any row does not parse or has
    another number of fields than the header (the exact parser then says which)."""
    try:
        with warnings.catch_warnings(), _text_lines(raw, "latin-1") as handle:
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            data = np.loadtxt(
                handle,
                delimiter=layout.delimiter,
                skiprows=layout.header_line + 1,
                comments=None,
                quotechar='"',
                encoding="latin-1",
                ndmin=2,
            )
    except ValueError:
        return None
    if data.shape[0] and data.shape[1] != len(layout.names):
        return None
    return data[:, columns]


def _text_lines(raw: RawInput, encoding: str) -> io.TextIOWrapper:
    """The input as text lines ended by LF, CRLF or CR (each kept at the line's end)."""
    return io.TextIOWrapper(raw.open(), encoding=encoding, errors="replace", newline="")


def _data_lines(raw: RawInput, layout: _TextLayout):
    """``(line_number, text)`` of each non-blank data line, line numbers 1-based."""
    with _text_lines(raw, layout.encoding) as handle:
        for number, line in enumerate(handle, start=1):
            if number > layout.header_line + 1 and line.strip():
                yield number, line


def _data_line_numbers(raw: RawInput, layout: _TextLayout) -> list[int]:
    return [number for number, _ in _data_lines(raw, layout)]


def _fields(line: str, number: int, layout: _TextLayout) -> list[str]:
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


def _parse_text_exactly(
    raw: RawInput, layout: _TextLayout, names: list[str], text_ok: set[str]
) -> dict[str, np.ndarray]:
    """Slow, exact parse: empty cells become NaN; a column in ``text_ok`` that is not all
    numbers comes back as text; any other cell that is not a number is an error."""
    columns = [layout.names.index(name) for name in names]
    cells: list[list[str]] = [[] for _ in names]
    line_numbers = []
    ends_with_newline = True
    for number, line in _data_lines(raw, layout):
        fields = _fields(line, number, layout)
        line_numbers.append(number)
        ends_with_newline = line.endswith(("\n", "\r"))
        for k, column in enumerate(columns):
            cells[k].append(fields[column].strip())
    if not line_numbers:
        raise FileFormatError("the file has a header row but no data rows")
    cut = None if ends_with_newline else line_numbers[-1]
    arrays = {
        name: _numbers(name, values, name in text_ok, line_numbers, cut)
        for name, values in zip(names, cells, strict=True)
    }
    _check_not_truncated(raw, layout, lambda: f"line {line_numbers[-1]}")
    return arrays


def _numbers(
    name: str, cells: list[str], text_ok: bool, line_numbers: list[int], cut_line: int | None
) -> np.ndarray:
    """A column of cells as float64 (empty cells NaN), or as text when allowed."""
    values = np.empty(len(cells))
    for row, cell in enumerate(cells):
        try:
            values[row] = float(cell) if cell else np.nan
        except ValueError:
            if text_ok:
                return np.array(cells, dtype=str)
            hint = ""
            if re.fullmatch(r"[-+]?\d+,\d+", cell):
                hint = " (a decimal comma? write decimal points)"
            elif line_numbers[row] == cut_line:
                hint = " (the last line has no newline: is the file truncated?)"
            raise FileFormatError(
                f"line {line_numbers[row]}, column {name!r}: {cell[:40]!r} is not a number{hint}"
            ) from None
    return values


# ---------------------------------------------------------------------------- chunks
#: bytes of a text file parsed by pyarrow at a time (its default block size): larger
#: blocks are not faster
_BLOCK_BYTES = 1 << 20


class _LineFinder:
    """The file line of data row ``i`` (zero-based, blank lines not counted), found by
    reading the file forward from the last row asked for (rows are asked for in order)."""

    def __init__(self, raw: RawInput, layout: _TextLayout):
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


def _stream_text(
    raw: RawInput, layout: _TextLayout, names: list[str], chunk_rows: int, text_ok: set[str]
) -> Iterator[Chunk]:
    """Chunks of at most ``chunk_rows`` rows of the columns ``names``, in file order."""
    done = 0
    finder = _LineFinder(raw, layout)
    arrow = _arrow_chunks(raw, layout, names, chunk_rows, text_ok, finder)
    if arrow is not None:
        try:
            for chunk in arrow:
                done = chunk.start + chunk.n_rows
                yield chunk
        except _ArrowFailed:
            yield from _line_chunks(raw, layout, names, chunk_rows, text_ok, skip=done)
            return
        if done == 0:
            raise FileFormatError("the file has a header row but no data rows")
        _check_not_truncated(raw, layout, lambda: finder(done - 1))
        return
    yield from _line_chunks(raw, layout, names, chunk_rows, text_ok, skip=0)


class _ArrowFailed(Exception):
    """pyarrow could not parse a block: the lines from the first row not yet given are
    read by the line parser, which names what is wrong."""


def _arrow_chunks(raw, layout, names, chunk_rows, text_ok, finder):
    """Chunks parsed by pyarrow's CSV reader, one block of whole lines at a time (not its
    streaming reader, which reads tens of MB ahead); None when pyarrow is missing or the
    file is whitespace-delimited. Raises :class:`_ArrowFailed` when a block does not
    parse, after the chunks before it."""
    if layout.delimiter is None or layout.data_offset is None:
        return None
    try:
        import pyarrow as pa
        import pyarrow.csv as pa_csv
    except ImportError:
        return None
    options = {
        "read_options": pa_csv.ReadOptions(column_names=layout.names, use_threads=False),
        "parse_options": pa_csv.ParseOptions(delimiter=layout.delimiter),
        "convert_options": pa_csv.ConvertOptions(
            include_columns=names,
            column_types={name: pa.string() if name in text_ok else pa.float64() for name in names},
            null_values=[""],
        ),
    }

    def chunks():
        pending: list = []  # parsed tables not yet given out
        pending_rows = 0
        start = 0
        with raw.open() as handle:
            handle.seek(layout.data_offset)
            for block, position in _line_blocks(handle, layout.data_offset):
                if block is not None:
                    try:
                        table = pa_csv.read_csv(pa.py_buffer(block), **options)
                    except pa.ArrowException:
                        raise _ArrowFailed from None
                    pending.append(table)
                    pending_rows += table.num_rows
                while pending_rows >= chunk_rows or (block is None and pending_rows):
                    table = pa.concat_tables(pending)
                    size = min(chunk_rows, pending_rows)
                    columns = {
                        name: _arrow_column(table.column(name)[:size], name in text_ok)
                        for name in names
                    }
                    rest = table.slice(size)
                    pending, pending_rows = [rest], rest.num_rows
                    yield Chunk(start, columns, finder, min(position, raw.size))
                    start += size

    return chunks()


def _line_blocks(handle, offset: int):
    """``(block, position)``: blocks of about :data:`_BLOCK_BYTES` of whole lines (cut
    after a line end; blank blocks left out), each with the byte position after it; a
    last ``(None, size)`` marks the end."""
    rest = b""
    position = offset
    while True:
        data = handle.read(_BLOCK_BYTES)
        if not data:
            if rest.strip():
                yield rest, position + len(rest)
            yield None, position + len(rest)
            return
        data = rest + data
        cut = max(data.rfind(b"\n"), data.rfind(b"\r")) + 1
        block, rest = data[:cut], data[cut:]
        position += len(block)
        if block.strip():
            yield block, position


def _arrow_column(column, text: bool) -> np.ndarray:
    """A parsed column as float64 (nulls NaN) or, for a text column, stripped text."""
    if text:
        return np.char.strip(np.asarray(column.to_pylist(), dtype=str))
    return column.to_numpy()


def _line_chunks(raw, layout, names, chunk_rows, text_ok, skip: int) -> Iterator[Chunk]:
    """Chunks of data lines from data row ``skip`` on, each parsed by numpy or, when it
    does not parse, exactly (naming the line of a bad cell). The progress is the bytes
    read (characters of the lines before the last chunk: close enough for a bar)."""
    columns = [layout.names.index(name) for name in names]
    lines = _data_lines(raw, layout)
    position = layout.data_offset or 0
    start = 0
    if skip:
        position += sum(len(line) for _, line in itertools.islice(lines, skip))
        start = skip
    batch = list(itertools.islice(lines, chunk_rows))
    if not batch:
        raise FileFormatError("the file has a header row but no data rows")
    while batch:
        following = list(itertools.islice(lines, chunk_rows))
        numbers = [number for number, _ in batch]
        position += sum(len(line) for _, line in batch)
        data = None if text_ok else _parse_lines_with_numpy(batch, layout, columns)
        if data is None:
            cut = numbers[-1] if not batch[-1][1].endswith(("\n", "\r")) else None
            arrays = _parse_lines_exactly(batch, layout, names, text_ok, cut)
        else:
            arrays = {name: data[:, k] for k, name in enumerate(names)}
        if not following:
            last_line = f"line {numbers[-1]}"
            _check_not_truncated(raw, layout, lambda last_line=last_line: last_line)
        done = raw.size if not following else min(position, raw.size)
        yield Chunk(start, arrays, _chunk_labels(start, numbers), done)
        start += len(batch)
        batch = following


def _chunk_labels(start: int, numbers: list[int]) -> Callable[[int], str]:
    return lambda row: f"line {numbers[row - start]}"


def _parse_lines_with_numpy(batch, layout: _TextLayout, columns: list[int]):
    """Columns (m, k) of some data lines parsed by numpy; None when any does not parse or
    has another number of fields than the header."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            data = np.loadtxt(
                [line for _, line in batch],
                delimiter=layout.delimiter,
                comments=None,
                quotechar='"',
                ndmin=2,
            )
    except ValueError:
        return None
    if data.shape[1] != len(layout.names):
        return None
    return data[:, columns]


def _parse_lines_exactly(batch, layout, names, text_ok, cut_line) -> dict[str, np.ndarray]:
    """Data lines parsed cell by cell (see :func:`_parse_text_exactly`); a column in
    ``text_ok`` comes back as text always."""
    columns = [layout.names.index(name) for name in names]
    cells: list[list[str]] = [[] for _ in names]
    numbers = []
    for number, line in batch:
        fields = _fields(line, number, layout)
        numbers.append(number)
        for k, column in enumerate(columns):
            cells[k].append(fields[column].strip())
    return {
        name: np.array(values, dtype=str)
        if name in text_ok
        else _numbers(name, values, False, numbers, cut_line)
        for name, values in zip(names, cells, strict=True)
    }


# ---------------------------------------------------------------------------- truncation
_EXPONENT = re.compile(r"[eE][-+]?\d*$")


def _exponent_digits(cell: str) -> int:
    """Digits of the exponent of a number's text (``1.5e-05`` -> 2), -1 without one."""
    found = _EXPONENT.search(cell)
    return -1 if found is None else sum(char.isdigit() for char in found.group())


def _check_not_truncated(raw: RawInput, layout: _TextLayout, last_line: Callable[[], str]) -> None:
    """Refuse a file whose last line has no newline and whose last value looks cut.

    The last value is compared with the same column in the lines before it: it is
    probably cut when it has fewer exponent digits than all of them (``1.934123e1`` among
    ``1.934123e14``), or when it is shorter than all of them by more than their exponent
    part (``1.93`` among ``1.934123e14``, ``0.12`` among ``0.123456``). ``last_line()``
    names the last line in the message.
    """
    tail = raw.tail(_TAIL_BYTES)
    if not tail or tail.endswith((b"\n", b"\r")) or raw.size <= (layout.data_offset or 0):
        return
    lines = _LINE_END.split(tail.decode(layout.encoding, errors="replace"))
    if raw.size > len(tail):
        lines = lines[1:]  # the first line of the tail may start mid-line
    lines = [line for line in lines if line.strip()][-101:]
    if len(lines) < 2:
        return
    try:
        last = split_cells(lines[-1], layout.delimiter)
        previous = [split_cells(line, layout.delimiter) for line in lines[:-1]]
    except csv.Error:
        return
    column = len(last) - 1
    others = [fields[column].strip() for fields in previous if len(fields) == len(last)]
    others = [cell for cell in others if cell and _is_number(cell)]
    cell = last[column].strip()
    if not others or not cell:
        return
    exponents = [_exponent_digits(other) for other in others]
    fewer_exponent_digits = min(exponents) > 0 and _exponent_digits(cell) < min(exponents)
    shortest = min(others, key=len)
    exponent_part = _EXPONENT.search(shortest)
    much_shorter = len(cell) < len(shortest) - (len(exponent_part.group()) if exponent_part else 0)
    if fewer_exponent_digits or much_shorter:
        name = layout.names[column] if column < len(layout.names) else f"column {column + 1}"
        raise FileFormatError(
            f"{last_line()} is probably truncated: the file ends without a "
            f"newline inside column {name!r}, whose last value {cell[:40]!r} is shorter than "
            f"the values above it (e.g. {shortest[:40]!r}); copy the file again completely"
        )


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


# ---------------------------------------------------------------------------- writing
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def _safe_text(cell: str) -> str:
    """A text cell a spreadsheet will not run as a formula: a leading ``= + - @``, tab or
    CR gets a ``'`` in front (OWASP CSV injection); text that is a number is kept."""
    if cell.startswith(_FORMULA_START) and not _is_number(cell):
        return "'" + cell
    return cell


def _quoted(cell: str, delimiter: str) -> str:
    cell = _safe_text(cell)
    if delimiter in cell or '"' in cell or "\n" in cell or "\r" in cell:
        return '"' + cell.replace('"', '""') + '"'
    return cell


def _text_cells(values: np.ndarray, delimiter: str) -> list[str]:
    if values.dtype.kind in "fi":
        return list(map(repr, values.tolist()))
    return [_quoted(cell, delimiter) for cell in values.tolist()]


class DelimitedChunkWriter:
    """Writes 1-D columns (float64, int64 or text) as delimited text one chunk at a time:
    the header row with the first chunk, then the rows, as :func:`write_csv` does at once.

    Parameters
    ----------
    path : Path
        The file to write.
    delimiter : str
        ``","`` or ``"\\t"``.
    """

    def __init__(self, path: Path, delimiter: str):
        self._handle = open(path, "w", encoding="utf-8", newline="\n")  # noqa: SIM115
        self._delimiter = delimiter
        self._started = False

    def write(self, arrays: dict[str, np.ndarray]) -> None:
        """Append rows (the header row first, with the first chunk)."""
        delimiter = self._delimiter
        if not self._started:
            self._handle.write(delimiter.join(_quoted(name, delimiter) for name in arrays) + "\n")
            self._started = True
        rows = len(next(iter(arrays.values()))) if arrays else 0
        for start in range(0, rows, _WRITE_CHUNK_ROWS):
            block = [
                _text_cells(values[start : start + _WRITE_CHUNK_ROWS], delimiter)
                for values in arrays.values()
            ]
            self._handle.write("\n".join(map(delimiter.join, zip(*block, strict=True))) + "\n")

    def close(self) -> None:
        """Finish the file."""
        self._handle.close()

    def abort(self) -> None:
        """Release the file after a failure (the caller removes it)."""
        self._handle.close()


def _write_delimited(path: Path, arrays: dict[str, np.ndarray], delimiter: str) -> None:
    writer = DelimitedChunkWriter(path, delimiter)
    try:
        writer.write(arrays)
    finally:
        writer.close()


def write_csv(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write 1-D columns (float64, int64 or text) as comma-separated text with a header row."""
    _write_delimited(path, arrays, ",")


def write_tsv(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write 1-D columns (float64, int64 or text) as tab-separated text with a header row."""
    _write_delimited(path, arrays, "\t")
