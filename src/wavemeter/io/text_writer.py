"""Writing CSV and TSV tables: the shortest text that reads back to the same float64.

Text cells a spreadsheet would run as a formula get a leading ``'`` (the OWASP
convention); cells holding the delimiter, a quote or a line end are quoted.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_csv", "write_tsv", "DelimitedChunkWriter"]

_WRITE_CHUNK_ROWS = 1 << 13  # rows turned into text at a time: bounds the strings held
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


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True
