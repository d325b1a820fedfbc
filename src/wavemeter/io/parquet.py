"""Parquet files: reading and writing, through pyarrow (the ``parquet`` extra).

Integer and floating-point columns are fields; only the columns used are read, after the
number of rows the file's metadata declares has been checked against the size limit. (The
per-column chunk metadata is not consulted: pyarrow aborts the interpreter on some damaged
footers when it is.)
pyarrow is imported when a file is read or written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import FileFormatError, InputError
from .source import RawInput, Source, check_allocation, library_errors

__all__ = ["read_parquet", "write_parquet", "require_pyarrow"]

_INSTALL = "pip install 'wavemeter[parquet]'"


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

    return Source({name: (rows,) for name in numeric}, load)


def write_parquet(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write 1-D columns (float64, int64 or text) as one Parquet table."""
    pa = require_pyarrow("writing")
    table = pa.table({name: pa.array(values) for name, values in arrays.items()})
    pa.parquet.write_table(table, path)
