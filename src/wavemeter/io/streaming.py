"""Reading a table of readings in chunks: memory bounded by the chunk, not the file.

:func:`iter_readings` opens a data file once, finds the columns and their units once from
its header or metadata (as :func:`~wavemeter.io.read_table` does, with the same code), and
yields the rows as :class:`~wavemeter.io.Table` chunks, in file order. How each format is
read in chunks:

- CSV/TSV: pyarrow's CSV reader a block of lines at a time when installed, else chunks of
  lines parsed by numpy; a chunk that does not parse is read cell by cell, which names the
  line of a bad cell, and a last line cut short is refused, as in a whole read (the same
  parsers, :mod:`~wavemeter.io.text`).
- Parquet: ``ParquetFile.iter_batches`` over the columns used.
- HDF5: slices of the datasets.
- NPZ: the members' streams, when each field's samples lie one after the other (1-D
  arrays; 2-D ones stored with the samples along their slow axis); else the fields used
  are read whole.
- MAT (v5 and v7.3): the fields used are read whole (the format is not read in parts).
- Standard input (``-``), a pipe or a device: read once into memory as
  :func:`~wavemeter.io.read_table` does, then parsed in chunks.

Invalid rows are flagged per chunk with their reason and file line. When they are not
allowed, the rows after the first invalid one are still read (not yielded) to count them
all, so the error says how many there are, as a whole read does. Checks that need a whole
column (a port column with no positive reading: dBm?) are made when the file has been read.
Progress is counted in rows: a text file's are counted by a fast pass over its line ends.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from ..exceptions import InputError, shown
from .checks import ColumnChecks
from .columns import ColumnRequest
from .convert import convert_rows
from .plan import ColumnPlan, plan_columns
from .reading import about_file, invalid_rows_error, open_noted
from .source import MAX_BYTES, Source, whole_chunks
from .table import Table

__all__ = ["iter_readings", "ReadingStream", "CHUNK_ROWS"]

#: rows per chunk by default
CHUNK_ROWS = 1 << 16
#: invalid rows described in messages
_DESCRIBED = 5


def iter_readings(
    path,
    request: ColumnRequest | None = None,
    *,
    chunk_rows: int = CHUNK_ROWS,
    need_x: bool = False,
    find_extras: bool | None = None,
    allow_invalid: bool = False,
    find_temperature: bool | None = None,
    max_bytes: int = MAX_BYTES,
    name: str | None = None,
) -> ReadingStream:
    """Open a data file and read its readings in chunks of at most ``chunk_rows`` rows.

    The columns, their units and the ports are found when this is called (errors about
    them are raised here, before any value is read); iterating the result reads the
    values.

    Parameters
    ----------
    path : str or Path
        As for :func:`~wavemeter.io.read_table` (``"-"``: standard input).
    request : ColumnRequest, optional
        Columns and units chosen by the user; anything left None is found by name.
    chunk_rows : int
        Rows per chunk (the last may have fewer), at least 1.
    need_x : bool
        Whether a frequency/wavelength column must exist.
    find_extras : bool, optional
        Look for a power monitor and a temperature column by name; default ``need_x``.
    allow_invalid : bool
        Yield invalid rows (flagged in each chunk's ``invalid``) instead of raising.
    find_temperature : bool, optional
        Look for a temperature column by name; default ``find_extras``.
    max_bytes : int
        The most bytes the values of one chunk may take (float64), and the most read from
        a pipe or standard input; fields that must be read whole (MAT, some NPZ) are
        limited as a whole.
    name : str, optional
        What the file is called in messages and in the chunks' ``source`` (default:
        ``path``; e.g. ``<stdin>`` for ``-``).

    Returns
    -------
    ReadingStream
        Iterable of :class:`~wavemeter.io.Table` chunks, each with ``row_index`` the rows'
        zero-based indices among the file's data rows and ``row_label`` naming them.

    Raises
    ------
    InputError, FileFormatError
        As :func:`~wavemeter.io.read_table`, every message starting with the file name;
        while iterating, for bad cells, invalid rows (unless ``allow_invalid``) and the
        whole-column checks, raised after the chunks before them were yielded.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.io import iter_readings
    >>> stream = iter_readings(folder / "sweep.csv", chunk_rows=64, need_x=True)
    >>> stream.port_names
    ('p1_w', 'p2_w', 'p3_w')
    >>> [chunk.powers_w.shape[0] for chunk in stream]  # 200 rows, 64 at a time
    [64, 64, 64, 8]
    """
    if isinstance(chunk_rows, bool) or not isinstance(chunk_rows, (int, np.integer)):
        raise InputError(
            f"chunk_rows must be a whole number, got {shown(chunk_rows)}", parameter="chunk_rows"
        )
    if chunk_rows < 1:
        raise InputError(f"chunk_rows must be at least 1, got {chunk_rows}", parameter="chunk_rows")
    label = Path(path if name is None else name)
    request = request or ColumnRequest()
    find_extras = need_x if find_extras is None else find_extras
    extras = (find_extras, find_extras if find_temperature is None else find_temperature)
    with about_file(label):
        source = open_noted(path, max_bytes, request, label, depth=4)
        plan = plan_columns(source, request, need_x=need_x, extras=extras)
    return ReadingStream(
        dataclasses.replace(plan, path=label), source, int(chunk_rows), allow_invalid
    )


class ReadingStream:
    """The readings of one file, read in chunks when iterated (once).

    Attributes
    ----------
    source : Path
        The file.
    port_names, port_units : tuple of str
        The ports, as every chunk has them.
    temperature_column, coarse_column, monitor_column : str or None
        The columns found for these roles.
    kept : tuple of str
        Columns copied as they are (``request.keep``).
    progress_total : tuple of (int, str)
        How far the read goes: ``(rows, "rows")``, the data rows the file declares or, for
        a text file, counted when first asked for by a fast pass over its line ends (a
        blank line after the header counts as a row).
    progress : int
        Data rows read so far, after the chunk last yielded.
    rows : int
        Data rows read so far (all of them once iteration ended).
    invalid_rows : int
        Invalid rows among them.
    invalid_examples : list of str
        The first invalid rows with their reasons, ``line 5 (P2_mW is NaN)``.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.io import iter_readings
    >>> stream = iter_readings(folder / "sweep.csv", chunk_rows=128)  # the columns found now
    >>> stream.port_names, stream.rows
    (('p1_w', 'p2_w', 'p3_w'), 0)
    >>> for chunk in stream:  # the values read while iterating, a chunk at a time
    ...     pass
    >>> stream.rows, stream.invalid_rows
    (200, 0)
    """

    def __init__(self, plan: ColumnPlan, source: Source, chunk_rows: int, allow_invalid: bool):
        self._plan = plan
        self._source = source
        self._chunk_rows = chunk_rows
        self._allow_invalid = allow_invalid
        self._started = False
        singles = plan.singles
        self.source = plan.path
        self.port_names = plan.port_names
        self.port_units = plan.port_units
        self.temperature_column = singles["temperature"].name if "temperature" in singles else None
        self.coarse_column = singles["coarse"].name if "coarse" in singles else None
        self.monitor_column = singles["monitor"].name if "monitor" in singles else None
        self.kept = tuple(plan.request.keep)
        self.progress = 0
        self.rows = 0
        self.invalid_rows = 0
        self.invalid_examples: list[str] = []

    @functools.cached_property
    def progress_total(self) -> tuple[int, str]:
        """``(rows, "rows")``: the data rows of the file (see the class's text)."""
        if self._source.count_rows is None:
            return _declared_rows(self._plan, self._source), "rows"
        with about_file(self.source):
            return self._source.count_rows(), "rows"

    def describe_invalid(self, limit: int = _DESCRIBED) -> str:
        """The first invalid rows read, with their reasons (as ``Table.describe_invalid``)."""
        return ", ".join(self.invalid_examples[:limit])

    def __iter__(self) -> Iterator[Table]:
        if self._started:
            raise InputError(f"{self.source}: the readings of a stream are read once")
        self._started = True
        with about_file(self.source):
            yield from self._chunks()

    def _raw_chunks(self):
        plan, source = self._plan, self._source
        text_ok = set(plan.request.keep)
        if source.chunks is None:
            return whole_chunks(source, plan.fields, self._chunk_rows, plan.sample_axes, text_ok)
        return source.chunks(plan.fields, self._chunk_rows, plan.sample_axes, text_ok)

    def _chunks(self) -> Iterator[Table]:
        checks = ColumnChecks()
        kinds: dict[str, str] = {}  # kept column -> "numbers" or "text", from its first chunk
        failed = False  # an invalid row not allowed was found: count the rest, yield nothing
        for chunk in self._raw_chunks():
            data = dict(chunk.columns)
            for name in self.kept:
                data[name] = _kept_values(
                    name, data[name], kinds, chunk.row_label, chunk.start, self._source.decimal
                )
            table = convert_rows(self._plan, data, chunk.start, chunk.row_label, checks)
            self.rows = self.progress = chunk.start + table.n_rows
            invalid = np.flatnonzero(table.invalid)
            if invalid.size:
                self.invalid_rows += invalid.size
                self.invalid_examples += _described(table, invalid[:_DESCRIBED])
                del self.invalid_examples[_DESCRIBED:]
                failed = failed or not self._allow_invalid
            if not failed:
                yield table
        checks.finish()
        if failed:
            raise invalid_rows_error(self.invalid_rows, self.describe_invalid())


def _declared_rows(plan: ColumnPlan, source: Source) -> int:
    """The rows of the fields a plan reads, as the file declares them (0 when unknown)."""
    rows = [
        shape[plan.sample_axes.get(name, 0)]
        for name in plan.fields
        if (shape := source.shapes[name]) != (-1,)
    ]
    return max(rows, default=0)


def _described(table: Table, rows: np.ndarray) -> list[str]:
    """``line 5 (P2_mW is NaN)`` for the given positions of invalid rows in ``table``."""
    return [
        f"{table.row_label(int(table.row_index[k]))} "
        f"({table.invalid_reasons[table.invalid_code[k]]})"
        for k in rows
    ]


def _kept_values(
    name: str,
    values: np.ndarray,
    kinds: dict[str, str],
    row_label: Callable,
    start: int,
    decimal: str,
) -> np.ndarray:
    """A kept column's chunk as numbers or text, the same throughout the file.

    A text file's kept column comes as text; it is numbers (empty cells NaN, the file's
    decimal mark ``decimal``) when every cell of its first chunk is a number, else text
    (as a whole read decides it from every cell). A later chunk of a column of numbers
    must hold numbers.
    """
    if values.dtype.kind != "U":
        kinds.setdefault(name, "numbers")
        return values
    numbers = _as_numbers(values, decimal)
    kind = kinds.setdefault(name, "text" if numbers is None else "numbers")
    if kind == "text":
        return values
    if numbers is None:
        bad = next(
            k for k, cell in enumerate(values) if _as_numbers(np.array([cell]), decimal) is None
        )
        raise InputError(
            f"kept column {name!r} holds numbers, then text at {row_label(start + bad)} "
            f"({values[bad][:40]!r}); a file read in chunks keeps a column as numbers or as "
            "text from its first rows on: make the column all numbers or all text",
            parameter="keep",
        )
    return numbers


def _as_numbers(cells: np.ndarray, decimal: str) -> np.ndarray | None:
    """Text cells as float64 (empty cells NaN; decimal mark ``decimal``), or None when one
    is not a number (with decimal commas, a cell holding ``.``)."""
    if decimal == ",":
        if np.char.find(cells, ".").max(initial=-1) >= 0:
            return None
        cells = np.char.replace(cells, ",", ".")
    try:
        return np.where(cells == "", "nan", cells).astype(float)
    except ValueError:
        return None
