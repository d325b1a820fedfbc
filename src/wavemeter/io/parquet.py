"""Parquet files: reading and writing, through pyarrow (the ``parquet`` extra).

Chunks are read with ``ParquetFile.iter_batches`` (only the columns used, one batch at a
time); :class:`ParquetChunkWriter` writes a table one chunk (row group) at a time.

Integer and floating-point columns are fields; only the columns used are read, after the
number of rows the file's metadata declares has been checked against the size limit. (The
per-column chunk metadata is not consulted: pyarrow aborts the interpreter on some damaged
footers when it is.)
pyarrow is imported when a file is read or written.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..exceptions import FileFormatError, InputError
from .source import Chunk, RawInput, Source, check_allocation, library_errors, sample_label

__all__ = ["read_parquet", "write_parquet", "require_pyarrow", "ParquetChunkWriter"]

_INSTALL = "pip install 'wavemeter[parquet]'"
#: bytes read at a time from a Parquet file read in chunks
_READ_BUFFER_BYTES = 1 << 20


def require_pyarrow(action: str):
    """The pyarrow module, or an error saying how to install it for ``action``."""
    try:
        import pyarrow
        import pyarrow.parquet  # noqa: F401
    except ImportError as exc:
        raise InputError(f"{action} Parquet needs pyarrow: {_INSTALL}") from exc
    return pyarrow


def read_parquet(raw: RawInput, max_bytes: int) -> Source:
    """The numeric columns of a Parquet file, read on demand."""
    pa = require_pyarrow("reading")
    errors = (pa.ArrowException, OSError, ValueError, TypeError, IndexError, KeyError)
    with library_errors("Parquet", errors):
        parquet = pa.parquet.ParquetFile(raw.file_or_buffer())
        rows = parquet.metadata.num_rows
        schema = parquet.schema_arrow
        names = [field.name for field in schema]
        numeric = [
            field.name
            for field in schema
            if pa.types.is_floating(field.type) or pa.types.is_integer(field.type)
        ]
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        raise FileFormatError(f"duplicate column names {duplicates}; rename them")

    def load(names, text_ok=()):
        check_allocation(f"{len(names)} columns of {rows} rows", 8 * rows * len(names), max_bytes)
        with library_errors("Parquet", errors):
            table = pa.parquet.read_table(raw.file_or_buffer(), columns=names)
            columns = {
                name: np.asarray(table.column(name).cast(pa.float64()).fill_null(np.nan))
                for name in names
            }
        if any(len(values) != rows for values in columns.values()):
            raise FileFormatError("the columns hold fewer rows than the file declares: damaged")
        return columns

    def chunks(names, chunk_rows, sample_axes=None, text_ok=()) -> Iterator[Chunk]:
        check_allocation(
            f"{len(names)} columns of {chunk_rows} rows", 8 * chunk_rows * len(names), max_bytes
        )
        start = 0
        with library_errors("Parquet", errors):
            # buffered reads: pages as needed, not whole column chunks of a row group
            parquet = pa.parquet.ParquetFile(
                raw.file_or_buffer(), buffer_size=_READ_BUFFER_BYTES, pre_buffer=False
            )
            batches = parquet.iter_batches(
                batch_size=chunk_rows, columns=list(names), use_threads=False
            )
            for batch in batches:
                columns = {
                    name: np.asarray(batch.column(name).cast(pa.float64()).fill_null(np.nan))
                    for name in names
                }
                start += batch.num_rows
                yield Chunk(start - batch.num_rows, columns, sample_label)
        if start != rows:
            raise FileFormatError("the columns hold fewer rows than the file declares: damaged")

    return Source({name: (rows,) for name in numeric}, load, chunks=chunks)


def write_parquet(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write 1-D columns (float64, int64 or text) as one Parquet table."""
    pa = require_pyarrow("writing")
    table = pa.table({name: pa.array(values) for name, values in arrays.items()})
    pa.parquet.write_table(table, path)


class ParquetChunkWriter:
    """Writes a Parquet table one chunk at a time (each chunk a row group).

    Parameters
    ----------
    path : Path
        The file to write (a temporary file; the caller renames it).
    """

    def __init__(self, path: Path):
        self._path = path
        self._writer = None

    def write(self, arrays: dict[str, np.ndarray]) -> None:
        """Append rows: 1-D columns (float64, int64 or text) of one length, the same
        columns and types at every call."""
        pa = require_pyarrow("writing")
        table = pa.table({name: pa.array(values) for name, values in arrays.items()})
        if self._writer is None:
            self._writer = pa.parquet.ParquetWriter(self._path, table.schema)
        elif table.schema != self._writer.schema:
            table = table.cast(self._writer.schema)
        self._writer.write_table(table)

    def close(self) -> None:
        """Finish the file."""
        if self._writer is not None:
            self._writer.close()

    def abort(self) -> None:
        """Release the file after a failure (the caller removes it)."""
        if self._writer is not None:
            self._writer.close()
