"""Reading and writing tables of readings and results: file formats, columns, units.

:func:`read_table` opens CSV/TSV (delimiter and decimal mark found, or given), HDF5, MAT
v5 and v7.3, NPZ and Parquet files, finds the frequency axis, the port columns, a power
monitor and a temperature by name (unit from a suffix or bracket: ``frequency_hz``,
``Wavelength (nm)``, ``P1_mW``, ``Port 3 [uW]``, ``DC CH1``), converts them to SI, flags
invalid rows (NaN, power-meter sentinels, implausible dBm, no light) and refuses values
that cannot be in their unit. :func:`write_table` writes named columns to CSV, TSV,
Parquet, HDF5 or NPZ at full float64 precision, atomically; :func:`iter_readings` and
:func:`table_writer` do the same a chunk of rows at a time, in memory bounded by the
chunk. What a file declares is checked against :data:`MAX_BYTES` before anything is
allocated. File readers know nothing of the numerics.

Modules: ``formats`` (the one table of formats; every data file is opened there), one per
format (``text`` with ``text_layout`` and ``text_writer``, ``hdf5``, ``mat``, ``npz``,
``parquet``), ``source`` (what readers share), ``columns`` (finding columns by name, units
in names), ``plan`` (a file's columns and units), ``convert`` (rows to SI, invalid
readings), ``checks`` (whole-column checks: plausible power units), ``table`` (the Table),
``reading`` (read_table), ``streaming`` (iter_readings).
"""

from ..units import SENTINEL_DBM
from .columns import ColumnRequest, port_key, split_unit
from .formats import FORMATS, table_format, table_writer, write_table
from .power_codes import MAX_DBM, SENTINEL_W
from .reading import read_table
from .source import MAX_BYTES
from .streaming import ReadingStream, iter_readings
from .table import Table

__all__ = [
    "ColumnRequest",
    "Table",
    "read_table",
    "write_table",
    "iter_readings",
    "ReadingStream",
    "table_writer",
    "table_format",
    "port_key",
    "split_unit",
    "FORMATS",
    "SENTINEL_W",
    "SENTINEL_DBM",
    "MAX_DBM",
    "MAX_BYTES",
]
