"""The one table of file formats: name, extensions, reader, writer; picking one for a file.

A file to read is recognised by its first bytes (HDF5, MATLAB, zip, Parquet signatures),
then by its extension; anything else is read as a text table. A file to write takes the
format asked for, else the one its extension names; an extension no writer knows is an
error (``q.xlsx`` is not silently written as CSV), a name without extension is CSV.
:func:`write_table` writes columns at once, :func:`table_writer` one chunk of rows at a
time; both atomically.
"""

from __future__ import annotations

import contextlib
import functools
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import STDOUT, atomic_path
from ..exceptions import InputError
from .hdf5 import HDF5ChunkWriter, read_hdf5, write_hdf5
from .mat import read_mat
from .npz import NPZChunkWriter, read_npz, write_npz
from .parquet import ParquetChunkWriter, read_parquet, require_pyarrow, write_parquet
from .source import Source, open_input
from .text import read_text
from .text_layout import check_dialect, refuse_text_chunk
from .text_writer import DelimitedChunkWriter, write_csv, write_tsv

__all__ = [
    "FileFormat",
    "FILE_FORMATS",
    "FORMATS",
    "open_source",
    "table_format",
    "write_table",
    "table_writer",
]


@dataclass(frozen=True)
class FileFormat:
    """A file format: how to read and write it and the extensions that name it.

    Attributes
    ----------
    name : str
        The format's name (``"csv"``, ``"hdf5"``), as given to ``write_table``.
    extensions : tuple of str
        File extensions (lower case, with the dot) that mean this format.
    read : callable
        ``read(raw, max_bytes) -> Source``; a text format's also takes the delimiter and
        the decimal mark, ``read(raw, max_bytes, delimiter, decimal)``.
    write : callable or None
        ``write(path, columns)`` with 1-D float64, int64 or text columns; None: read only.
    chunk_writer : callable or None
        ``chunk_writer(path)`` returns a writer with ``write(columns)`` appending rows and
        ``close()`` finishing the file, ``abort()`` releasing it after a failure.
    label : str
        The format as users know it (``"CSV"``, ``"HDF5"``), for messages.
    text : bool
        A delimited text format: its cells have a delimiter and a decimal mark.
    """

    name: str
    extensions: tuple[str, ...]
    read: Callable[..., Source]
    write: Callable[[Path, dict[str, np.ndarray]], None] | None
    chunk_writer: Callable[[Path], object] | None = None
    label: str = ""
    text: bool = False


#: every format the package reads, and writes where ``write`` is set
FILE_FORMATS = (
    FileFormat(
        "csv",
        (".csv", ".txt", ".dat"),
        read_text,
        write_csv,
        functools.partial(DelimitedChunkWriter, delimiter=","),
        label="CSV",
        text=True,
    ),
    FileFormat(
        "tsv",
        (".tsv",),
        read_text,
        write_tsv,
        functools.partial(DelimitedChunkWriter, delimiter="\t"),
        label="TSV",
        text=True,
    ),
    FileFormat(
        "parquet",
        (".parquet", ".pq"),
        read_parquet,
        write_parquet,
        ParquetChunkWriter,
        label="Parquet",
    ),
    FileFormat(
        "hdf5", (".h5", ".hdf5", ".hdf"), read_hdf5, write_hdf5, HDF5ChunkWriter, label="HDF5"
    ),
    FileFormat("npz", (".npz",), read_npz, write_npz, NPZChunkWriter, label="NPZ"),
    FileFormat("mat", (".mat",), read_mat, None, label="MATLAB"),
)
_BY_NAME = {file_format.name: file_format for file_format in FILE_FORMATS}
#: output formats of :func:`write_table`
FORMATS = tuple(file_format.name for file_format in FILE_FORMATS if file_format.write)


def _by_extension(suffix: str) -> FileFormat | None:
    return next((f for f in FILE_FORMATS if suffix in f.extensions), None)


def _format_of(head: bytes, suffix: str) -> FileFormat:
    """The format of a file to read, from its first bytes, else its extension."""
    if head.startswith(b"\x89HDF") or head[512:516] == b"\x89HDF":
        return _BY_NAME["mat" if suffix == ".mat" else "hdf5"]
    if head.startswith(b"MATLAB 5.0") or suffix == ".mat":
        return _BY_NAME["mat"]
    if head.startswith(b"PK\x03\x04"):
        return _BY_NAME["npz"]
    if head.startswith(b"PAR1"):
        return _BY_NAME["parquet"]
    return _BY_NAME["csv"]  # every text table: the delimiter is sniffed


def _refuse_stream_chunk(head: bytes, chunk: bytes, suffix: str) -> str | None:
    """Stop reading a stream early when it can be no table: text holding NUL bytes."""
    if len(head) < 1024:
        return None  # too little seen yet to tell
    if not head.strip(b"\x00"):
        return "holds only NUL bytes: it is no table of any format"
    if _format_of(head, suffix).name != "csv":
        return None  # a binary format: read it whole, up to the limit
    return refuse_text_chunk(head, chunk)


def open_source(path, max_bytes: int, delimiter=None, decimal=None) -> Source:
    """The fields of the data file at ``path`` (``-``: standard input), read by its format.

    A regular file is read in place; a pipe, device or standard input is read once, at
    most ``max_bytes`` bytes, then parsed from memory. Every data file is opened here.

    Parameters
    ----------
    path : str or Path
        The file.
    max_bytes : int
        The size limit (see :func:`~wavemeter.io.read_table`).
    delimiter, decimal : str, optional
        The column delimiter and decimal mark of a text table (default: found from the
        file); given for a file of another format, they are refused.
    """
    check_dialect(delimiter, decimal)
    suffix = Path(str(path)).suffix.lower()
    raw = open_input(path, max_bytes, lambda head, chunk: _refuse_stream_chunk(head, chunk, suffix))
    file_format = _format_of(raw.head(1024), raw.suffix)
    if file_format.text:
        return file_format.read(raw, max_bytes, delimiter, decimal)
    for parameter, value in (("delimiter", delimiter), ("decimal", decimal)):
        if value is not None:
            raise InputError(
                f"is a {file_format.label} file, not a text table: it has no {parameter} "
                f"(given {value!r}); leave the {parameter} out",
                parameter=parameter,
            )
    return file_format.read(raw, max_bytes)


def table_format(path, file_format: str | None = None) -> str:
    """Output format: ``file_format`` if given, else from the file extension.

    Parameters
    ----------
    path : str or Path
        The output file; ``"-"`` (standard output) and names without an extension are CSV.
    file_format : {"csv", "tsv", "parquet", "hdf5", "npz"}, optional
        The format asked for; it wins over the extension.

    Raises
    ------
    InputError
        For an unknown format, or an extension no writer knows (``parameter`` is
        ``"file_format"``).

    Examples
    --------
    >>> from wavemeter.io import table_format
    >>> table_format("out.csv"), table_format("out.parquet"), table_format("out.txt", "tsv")
    ('csv', 'parquet', 'tsv')
    """
    if file_format is not None:
        if file_format not in FORMATS:
            raise InputError(
                f"format must be one of {', '.join(FORMATS)}; got {file_format!r}",
                parameter="file_format",
            )
        return file_format
    suffix = Path(str(path)).suffix.lower()
    if str(path) == STDOUT or not suffix:
        return "csv"
    found = _by_extension(suffix)
    if found is None or found.write is None:
        what = "MAT files" if found is not None else f"{suffix!r} files"
        known = ", ".join(ext for f in FILE_FORMATS if f.write for ext in f.extensions)
        raise InputError(
            f"{path}: cannot write {what}; name the file with one of the extensions {known}, "
            f"or choose a format ({', '.join(FORMATS)})",
            parameter="file_format",
        )
    return found.name


def write_table(path, columns: dict[str, np.ndarray], file_format: str | None = None) -> None:
    """Write named 1-D columns to a file, atomically, floats at full float64 precision.

    Parameters
    ----------
    path : str or Path
        Output file; ``"-"`` writes to standard output.
    columns : dict of str to array_like, each shape (N,)
        Column name (with its unit suffix, e.g. ``frequency_hz``) to values: numbers, or
        text (kept columns of a text file).
    file_format : {"csv", "tsv", "parquet", "hdf5", "npz"}, optional
        Default: from the extension of ``path`` (``.parquet``, ``.h5``, ``.npz``, ``.tsv``,
        ``.csv``/``.txt``/``.dat``; CSV without extension). CSV floats are the shortest
        text that reads back to the same float64; CSV text cells that a spreadsheet would
        run as a formula get a leading ``'``.

    Raises
    ------
    InputError
        For an unknown format or extension, columns of different lengths or not 1-D, a
        missing folder; nothing is written then.

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
    >>> from wavemeter.io import read_table
    >>> write_table(folder / "sweep.npz", columns)  # the format from the extension
    >>> print(np.array_equal(read_table(folder / "sweep.npz").x_hz, f_hz))  # to the last bit
    True
    """
    writer = _BY_NAME[table_format(path, file_format)].write
    arrays = {str(name): _column_array(name, values) for name, values in columns.items()}
    lengths = {len(values) for values in arrays.values()}
    if len(lengths) > 1:
        raise InputError(f"columns to write have different lengths: {sorted(lengths)}")
    if writer is write_parquet:
        require_pyarrow("writing")
    if str(path) == STDOUT:
        _write_to_stdout(writer, arrays)
        return
    with atomic_path(path) as temporary:
        writer(temporary, arrays)


@contextlib.contextmanager
def table_writer(path, file_format: str | None = None) -> Iterator[Callable[[dict], None]]:
    """Yield ``write(columns)``, which appends rows to a table file; atomic as a whole.

    The rows go to a temporary file beside ``path`` (for ``"-"``, standard output, a
    temporary folder), renamed onto ``path`` (copied to standard output) when the block
    ends without error; on any error, also ``KeyboardInterrupt``, no output is left and
    an existing ``path`` is untouched. One chunk is held in memory at a time (an NPZ
    archive's columns are spooled to disk beside ``path`` until the end).

    Parameters
    ----------
    path : str or Path
        Output file; ``"-"`` writes to standard output.
    file_format : {"csv", "tsv", "parquet", "hdf5", "npz"}, optional
        As for :func:`write_table`.

    Yields
    ------
    callable
        ``write(columns)``: columns as for :func:`write_table`, each shape (m,), the same
        names in the same order at every call.

    Raises
    ------
    InputError
        As :func:`write_table`; also when a chunk has other columns than the first.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from wavemeter.io import read_table, table_writer
    >>> path = Path(tempfile.mkdtemp()) / "frequencies.csv"
    >>> with table_writer(path) as write:  # renamed into place at the end
    ...     for start in (0, 2):
    ...         write({"frequency_hz": 193.4e12 + np.arange(start, start + 2) * 1e9})
    >>> for line in path.read_text().splitlines():  # full float64 precision
    ...     print(line)
    frequency_hz
    193400000000000.0
    193401000000000.0
    193402000000000.0
    193403000000000.0
    """
    chosen = _BY_NAME[table_format(path, file_format)]
    if chosen.write is write_parquet:
        require_pyarrow("writing")
    with contextlib.ExitStack() as stack:
        if str(path) == STDOUT:
            temporary = Path(stack.enter_context(tempfile.TemporaryDirectory())) / "table"
        else:
            temporary = stack.enter_context(atomic_path(path))
        writer = chosen.chunk_writer(temporary)
        columns: list[str] = []

        def write(chunk: dict) -> None:
            arrays = {str(name): _column_array(name, values) for name, values in chunk.items()}
            if len({len(values) for values in arrays.values()}) > 1:
                lengths = sorted({len(values) for values in arrays.values()})
                raise InputError(f"columns to write have different lengths: {lengths}")
            if columns and list(arrays) != columns:
                raise InputError(
                    f"a chunk to write has columns {list(arrays)}, the first had {columns}"
                )
            columns[:] = list(arrays)
            writer.write(arrays)

        try:
            yield write
        except BaseException:
            writer.abort()
            raise
        writer.close()
        if str(path) == STDOUT:
            sys.stdout.flush()
            with open(temporary, "rb") as handle:
                shutil.copyfileobj(handle, sys.stdout.buffer)
            sys.stdout.buffer.flush()


def _write_to_stdout(writer, arrays: dict[str, np.ndarray]) -> None:
    with tempfile.TemporaryDirectory() as folder:
        temporary = Path(folder) / "table"
        writer(temporary, arrays)
        sys.stdout.flush()
        with open(temporary, "rb") as handle:
            shutil.copyfileobj(handle, sys.stdout.buffer)
        sys.stdout.buffer.flush()


def _column_array(name, values) -> np.ndarray:
    array = np.asarray(values)
    if array.ndim != 1:
        raise InputError(f"column {name!r} to write must be 1-D, got shape {array.shape}")
    if array.dtype.kind in "iub":
        # counts and bit masks (the quality flags) stay integers
        return array.astype(np.int64)
    if array.dtype.kind == "f":
        return array.astype(float)
    return array.astype(str)
