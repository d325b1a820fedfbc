"""What a delimited text table looks like: encoding, header row, delimiter, decimal mark.

The header is the first line that is neither blank nor a ``#`` comment; an Excel ``sep=X``
first line names the delimiter and is no header. The delimiter is the one asked for, else
the one a ``sep=`` line names, else sniffed from the header and the rows after it (tab,
comma, semicolon, runs of spaces; ties go to the first). The decimal mark is the one asked
for, else ``.``, or ``,`` for a ``;``-separated file whose numbers are written with
decimal commas (a note says so). A cell is a number by Python's ``float`` rules with that
decimal mark; with decimal commas a cell holding ``.`` is not a number (``1.500`` may
mean fifteen hundred). :class:`LineCells` applies the same rules to the lines of a stream,
which come one at a time. :func:`check_not_truncated` tells from a file's last bytes
whether its last line was cut.
"""

from __future__ import annotations

import csv
import itertools
import math
import re
import warnings
from dataclasses import dataclass

from ..exceptions import FileFormatError, InputError, InputNote
from .source import RawInput

__all__ = [
    "TextLayout",
    "sniff_layout",
    "check_dialect",
    "excel_separator",
    "split_cells",
    "column_names",
    "parse_number",
    "refuse_text_chunk",
    "LineCells",
    "is_number",
    "check_not_truncated",
]

#: bytes read to find the layout (the header and the first rows must lie within)
_HEAD_BYTES = 1 << 16
#: bytes read from the end to tell whether the last line is cut
_TAIL_BYTES = 1 << 16
#: line ends, as Python's universal newlines: LF, CRLF, CR
_LINE_END = re.compile(r"\r\n|\n|\r")
_LINE_END_BYTES = re.compile(rb"\r\n|\n|\r")
_DELIMITERS = ("\t", ",", ";", None)  # None: runs of whitespace; ties go to the first
_DELIMITER_NAMES = {"\t": "tab", ",": "comma", ";": "semicolon", None: "spaces"}
#: the delimiter value that means runs of spaces and tabs
WHITESPACE = " "
_NO_DELIMITER = set(".\"#+-'\r\n")
#: an Excel ``sep=X`` first line, maybe quoted, maybe padded with delimiters
_SEP_LINE = re.compile(r'^(?P<quote>"?)sep=(?P<sep>[^\r\n])(?P=quote)(?P=sep)*\s*$', re.IGNORECASE)
_COMMA_NUMBER = re.compile(r"[-+]?(?:\d+,\d*|,\d+)(?:[eE][-+]?\d+)?")
_POINT_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+)(?:[eE][-+]?\d+)?")


@dataclass(frozen=True)
class TextLayout:
    """The layout of a text table, found from its first bytes.

    Attributes
    ----------
    encoding : str
        ``"utf-8"`` or, when the first bytes are not UTF-8, ``"latin-1"``.
    delimiter : str or None
        The column delimiter; None: runs of whitespace.
    decimal : str
        The decimal mark, ``"."`` or ``","``.
    names : list of str
        The column names of the header row.
    header_line : int
        Zero-based index of the header line.
    data_offset : int or None
        Byte offset of the first line after the header (None: not within the first bytes).
    note : str or None
        What was chosen that the user did not say (decimal commas), for a note.
    """

    encoding: str
    delimiter: str | None
    decimal: str
    names: list[str]
    header_line: int
    data_offset: int | None
    note: str | None = None


def check_dialect(delimiter, decimal) -> None:
    """Refuse a delimiter or decimal mark no text table can have, and the two alike.

    Parameters
    ----------
    delimiter : str or None
        One character (``" "``: runs of spaces and tabs); None: found from the file.
    decimal : {".", ",", None}
        The decimal mark; None: found from the file.

    Raises
    ------
    InputError
        Naming the parameter (``delimiter`` or ``decimal``) at fault.
    """
    if delimiter is not None and (
        not isinstance(delimiter, str)
        or len(delimiter) != 1
        or delimiter.isalnum()
        or delimiter in _NO_DELIMITER
    ):
        raise InputError(
            f"delimiter must be one character such as ',', ';', '\\t' or ' ' (runs of "
            f"spaces), not a letter, digit, quote or one of . + - #; got {delimiter!r}",
            parameter="delimiter",
        )
    if decimal is not None and decimal not in (".", ","):
        raise InputError(f"decimal must be '.' or ','; got {decimal!r}", parameter="decimal")
    if delimiter is not None and delimiter == decimal:
        raise InputError(
            f"the delimiter and the decimal mark cannot both be {decimal!r}: 1{decimal}5 "
            "would be two cells and one number; give another delimiter or decimal mark",
            parameter="decimal",
        )


def excel_separator(line: str) -> str | None:
    """The delimiter an Excel ``sep=X`` line names (``sep=;`` -> ``";"``), else None.

    A line naming a character that cannot be a delimiter (``sep=.``) raises
    FileFormatError.
    """
    found = _SEP_LINE.match(line.lstrip("\ufeff").rstrip("\r\n"))
    if found is None:
        return None
    separator = found.group("sep")
    try:
        check_dialect(separator, None)
    except InputError:
        raise FileFormatError(
            f"the first line {line.strip()[:20]!r} names {separator!r} as the delimiter, "
            "which cannot be one; give the delimiter",
            parameter="delimiter",
        ) from None
    return separator


def refuse_text_chunk(head: bytes, chunk: bytes) -> str | None:
    """Why a chunk of a text stream cannot be a table (None when it can)."""
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "is UTF-16 text: save it as UTF-8 or ASCII"
    if b"\x00" in chunk:
        return "holds NUL bytes: it is not a text table (a binary file of an unknown format?)"
    return None


def split_cells(line: str, delimiter: str | None) -> list[str]:
    """The cells of one text line: CSV quoting with ``delimiter``, or whitespace when None."""
    if delimiter is None:
        return [cell.strip('"') for cell in line.split()]
    return next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])


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


def parse_number(cell: str, decimal: str) -> float:
    """The number in a stripped cell (NaN when empty), by ``float``'s rules with the
    decimal mark ``decimal``; raises ValueError when it is none."""
    if not cell:
        return math.nan
    if decimal == ",":
        if "." in cell:
            raise ValueError(cell)
        cell = cell.replace(",", ".")
    return float(cell)


def is_number(cell: str, decimal: str = ".") -> bool:
    """Whether a stripped cell is a number (see :func:`parse_number`)."""
    try:
        parse_number(cell, decimal)
    except ValueError:
        return False
    return True


def _decimal_comma_note(delimiter: str | None) -> str:
    """The note of a table read with decimal commas it did not ask for."""
    return f"read as {delimiter!r}-separated with decimal commas"


def _decode(head: bytes) -> tuple[str, str]:
    try:
        return head.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError as exc:
        if exc.start >= len(head) - 3:  # a multi-byte character cut by the read size
            return head[: exc.start].decode("utf-8-sig"), "utf-8"
        return head.decode("latin-1"), "latin-1"


def sniff_layout(raw: RawInput, delimiter: str | None = None, decimal: str | None = None):
    """The layout of a text table from its first 64 kB.

    Parameters
    ----------
    raw : RawInput
        The file.
    delimiter : str, optional
        The delimiter asked for (``" "``: runs of spaces and tabs); default: the one a
        ``sep=`` first line names, else sniffed.
    decimal : {".", ","}, optional
        The decimal mark asked for; default ``.``, or ``,`` in a ``;``-separated file
        whose first rows hold decimal commas and no decimal points.

    Returns
    -------
    TextLayout

    Raises
    ------
    InputError
        For a delimiter or decimal mark that cannot be (see :func:`check_dialect`).
    FileFormatError
        For an empty, UTF-16 or binary file, no header or data rows, a delimiter that
        cannot be told or splits the header into one column, a duplicate column name.
    """
    check_dialect(delimiter, decimal)
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
    declared = excel_separator(lines[0]) if lines else None
    header_line = next(
        (
            i
            for i, line in enumerate(lines)
            if line.strip() and not line.lstrip().startswith("#") and (i or declared is None)
        ),
        None,
    )
    if header_line is None:
        raise FileFormatError("no header row: the file holds only comments or blank lines")
    sample = [line for line in lines[header_line + 1 : header_line + 6] if line.strip()]
    if not sample:
        raise FileFormatError("the file has a header row but no data rows")
    header = lines[header_line]
    chosen = delimiter if delimiter is not None else declared
    if chosen is not None:
        found = None if chosen == WHITESPACE else chosen
        if found is not None and found == decimal:
            raise FileFormatError(
                f"the first line names {found!r} as the delimiter, and it is the decimal mark "
                "asked for; give another decimal mark",
                parameter="decimal",
            )
        names = split_cells(header, found)
        if len(names) < 2:
            shown = _DELIMITER_NAMES.get(found, repr(found))
            said = " (as its sep= line says)" if delimiter is None else ""
            raise FileFormatError(
                f"the header row is a single column when split at {shown}{said}: is that the "
                "delimiter? give the delimiter",
                parameter="delimiter",
            )
    else:
        found, names = _sniff_delimiter(header, sample, exclude=decimal)
    if decimal is None:
        rows = itertools.islice((line for line in lines[header_line + 1 :] if line.strip()), 200)
        commas = found == ";" and _has_decimal_commas(rows, found)
        decimal = "," if commas else "."
        note = _decimal_comma_note(found) if commas else None
    else:
        note = None
    ends = [end.end() for end in itertools.islice(_LINE_END_BYTES.finditer(head), header_line + 1)]
    data_offset = ends[header_line] if len(ends) > header_line else None
    return TextLayout(encoding, found, decimal, column_names(names), header_line, data_offset, note)


def _sniff_delimiter(header: str, sample: list[str], exclude: str | None):
    """The delimiter (None: whitespace) most rows agree on with the header, and the header's
    cells split at it; ``exclude`` (the decimal mark asked for) is no candidate."""
    tried = [delimiter for delimiter in _DELIMITERS if delimiter is None or delimiter != exclude]
    candidates = []  # (rows agreeing with the header, priority, delimiter, names)
    for priority, delimiter in enumerate(tried):
        names = split_cells(header, delimiter)
        if len(names) >= 2:
            widths = (len(split_cells(line, delimiter)) for line in sample)
            agreeing = sum(width in (len(names), len(names) + 1) for width in widths)
            candidates.append((agreeing, -priority, delimiter, names))
    if not candidates:
        shown = ", ".join(_DELIMITER_NAMES[delimiter] for delimiter in tried)
        raise FileFormatError(
            f"cannot tell the column delimiter (tried {shown}): the header row has a single column"
        )
    _, _, delimiter, names = max(candidates, key=lambda candidate: candidate[:2])
    return delimiter, names


def _has_decimal_commas(lines, delimiter: str) -> bool:
    """Whether the cells of ``lines`` (the first 200 data lines) hold numbers with decimal
    commas and none with a decimal point."""
    commas = False
    for line in lines:
        try:
            cells = split_cells(line, delimiter)
        except csv.Error:
            continue
        for cell in cells:
            cell = cell.strip().strip('"').strip()
            if _POINT_NUMBER.fullmatch(cell):
                return False
            commas = commas or _COMMA_NUMBER.fullmatch(cell) is not None
    return commas


class LineCells:
    """The cells and numbers of a stream's lines, which arrive one at a time.

    The delimiter is the one asked for, else found in the header line: tab when it holds
    one, else ``;`` when it holds one and no comma, else ``,``. The decimal mark is the one
    asked for, else ``.``; in a ``;``-separated stream the first number written with a
    decimal mark decides (a decimal comma is noted, :class:`~wavemeter.exceptions.InputNote`).

    Parameters
    ----------
    header : str
        The header line.
    delimiter : str, optional
        As for :func:`sniff_layout`.
    decimal : {".", ","}, optional
        As for :func:`sniff_layout`.
    source : str
        What the stream is called in the note.
    """

    def __init__(self, header: str, delimiter=None, decimal=None, source: str = "<input>"):
        check_dialect(delimiter, decimal)
        if delimiter is None:
            if "\t" in header:
                delimiter = "\t"
            else:
                delimiter = ";" if ";" in header and "," not in header else ","
        self.delimiter = None if delimiter == WHITESPACE else delimiter
        self.decimal = decimal if decimal is not None or self.delimiter == ";" else "."
        self._source = source

    def split(self, line: str) -> list[str]:
        """The cells of a line (raises csv.Error for a line that cannot be split)."""
        return split_cells(line, self.delimiter)

    def number(self, cell: str) -> float:
        """The number in a stripped cell (NaN when empty); raises ValueError when none."""
        if self.decimal is None:
            if _COMMA_NUMBER.fullmatch(cell):
                self.decimal = ","
                warnings.warn(
                    InputNote(f"{self._source}: {_decimal_comma_note(self.delimiter)}"),
                    stacklevel=2,
                )
            elif "." in cell:
                self.decimal = "."
        return parse_number(cell, self.decimal or ".")


# ---------------------------------------------------------------------------- truncation
_EXPONENT = re.compile(r"[eE][-+]?\d*$")


def _exponent_digits(cell: str) -> int:
    """Digits of the exponent of a number's text (``1.5e-05`` -> 2), -1 without one."""
    found = _EXPONENT.search(cell)
    return -1 if found is None else sum(char.isdigit() for char in found.group())


def check_not_truncated(raw: RawInput, layout: TextLayout, last_line) -> None:
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
    others = [cell for cell in others if cell and is_number(cell, layout.decimal)]
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
