"""Reading and writing tables of readings and results: file formats, columns, units.

:func:`read_table` opens CSV/TSV (delimiter sniffed), HDF5, MAT v5 and v7.3, NPZ and Parquet
files, finds the frequency axis, the port columns, a power monitor and a temperature by
name (unit from a suffix or bracket: ``frequency_hz``, ``Wavelength (nm)``, ``P1_mW``,
``Port 3 [uW]``, ``DC CH1``), converts them to SI and flags invalid rows (NaN, power-meter
sentinels, no light). :func:`write_table` writes named columns to CSV, Parquet, HDF5 or NPZ
at full float64 precision, atomically. File readers know nothing of the numerics.
"""

from __future__ import annotations

import csv
import dataclasses
import re
import warnings
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..exceptions import InputError
from ..units import (
    FREQUENCY_UNITS,
    WAVELENGTH_UNITS,
    axis_to_hz,
    canonical_unit,
    power_to_w,
    temperature_to_k,
)

__all__ = [
    "ColumnRequest",
    "Table",
    "read_table",
    "write_table",
    "table_format",
    "port_key",
    "split_unit",
    "FORMATS",
    "SENTINEL_W",
    "SENTINEL_DBM",
]

#: output formats of :func:`write_table`
FORMATS = ("csv", "tsv", "parquet", "hdf5", "npz")
#: raw readings above this (any linear unit) are instrument "no reading" codes (9.91e37)
SENTINEL_W = 1e20
#: dBm readings at or below this are a power meter's "no reading" code
SENTINEL_DBM = -200.0
#: the most ports a 2-D port array may have; the other axis holds the samples
MAX_PORTS = 64

_EXTENSIONS = {
    ".csv": "csv",
    ".txt": "csv",
    ".dat": "csv",
    ".tsv": "tsv",
    ".parquet": "parquet",
    ".pq": "parquet",
    ".h5": "hdf5",
    ".hdf5": "hdf5",
    ".hdf": "hdf5",
    ".mat": "mat",
    ".npz": "npz",
}
_HEAD_BYTES = 1 << 16
_CSV_CHUNK_ROWS = 1 << 16


# ---------------------------------------------------------------------------- names and roles
def _normalise(text: str) -> str:
    return re.sub(r"[\s_\-]+", " ", text.strip().lower()).strip()


_BRACKETED = re.compile(r"^(.*?)\s*[\[({]\s*([^\])}]*?)\s*[\])}]\s*$")
_LAST_TOKEN = re.compile(r"^(.*?[^\s_\-])[\s_\-]+([^\s_\-]+)$")

_X_WORDS = r"freq|frequency|optical frequency|f|nu|ν|wavelength|wave length|lambda|λ|wl"
_X_ROLE = re.compile(
    rf"^(?:(?:true|truth|ref|reference|set|laser|source|known|nominal|target) )?(?:{_X_WORDS})$"
    r"|^truth$"
)
_WAVELENGTH_WORD = re.compile(r"(wave|lambda|λ|wl)")
_PORT_FAMILY = r"p|port|ch|channel|pd|out|output|power|det|detector|photodiode|signal|sig"
_PORT_ROLE = re.compile(
    rf"^((?:(?:dc|ac|pd|det|detector|photodiode|optical) )?(?:{_PORT_FAMILY})) ?(\d+)$"
)
_PORT_MATRIX_ROLE = re.compile(
    r"^(?:p|power|powers|port|ports|port powers|pd|detector|detectors|signal|signals|"
    r"readings|channels|ch|dc|v|voltages|intensity|intensities)$"
)
_MONITOR_ROLE = re.compile(
    r"^(?:power monitor|monitor|mon|pm|monitor power|input power|source power|laser power|"
    r"tap|tap power|reference power|ref power)$"
)
_TEMPERATURE_ROLE = re.compile(r"^(?:(?:chip|stage|tec|device|sensor) )?(?:temperature|temp)$")


def split_unit(name: str) -> list[tuple[str, str | None]]:
    """Readings of a column name as ``(base, unit)``: the unit from a bracket or a suffix.

    ``"Wavelength (nm)"`` -> ``[("Wavelength", "nm")]``; ``"P1_mW"`` ->
    ``[("P1_mW", None), ("P1", "mW")]``; ``"DC CH1"`` -> ``[("DC CH1", None), ("DC", "CH1")]``.
    The caller keeps the reading whose base names a role; the unit is checked when used.
    """
    bracketed = _BRACKETED.match(name)
    if bracketed and bracketed.group(1):
        return [(bracketed.group(1), bracketed.group(2))]
    readings: list[tuple[str, str | None]] = [(name, None)]
    suffixed = _LAST_TOKEN.match(name.strip())
    if suffixed:
        readings.append((suffixed.group(1), suffixed.group(2)))
    return readings


def _known_unit(unit: str | None, kind: str) -> str | None:
    if unit is None:
        return None
    try:
        return canonical_unit(unit, kind)
    except ValueError:
        return None


def port_key(name: str) -> str:
    """A port column's identity without its unit: ``"Port 3 [uW]"`` and ``"port_3_mW"``
    both give ``"port3"``. Used to match a data file's ports to a calibration's."""
    base = name
    for reading_base, unit in split_unit(name):
        if unit is not None and (_known_unit(unit, "power") or _BRACKETED.match(name)):
            base = reading_base
    return re.sub(r"[^0-9a-zµμ]", "", base.lower())


@dataclass(frozen=True)
class _Role:
    """A column found by name: its role, the unit token in its name, a sort key."""

    name: str
    unit: str | None
    order: int = 0
    family: str = ""


def _match_role(name: str, pattern: re.Pattern) -> _Role | None:
    leaf = name.rsplit("/", 1)[-1]
    for base, unit in split_unit(leaf):
        found = pattern.match(_normalise(base))
        if found:
            groups = found.groups()
            order = int(groups[1]) if len(groups) > 1 and groups[1] else 0
            family = _normalise(groups[0]) if groups else ""
            return _Role(name, unit, order, family)
    return None


def _explicit_role(name: str, kind: str, unit_override: str | None) -> _Role:
    """A column the user named: its unit from the override, a bracket or a known suffix."""
    if unit_override is not None:
        return _Role(name, unit_override)
    leaf = name.rsplit("/", 1)[-1]
    for _, unit in reversed(split_unit(leaf)):
        if _BRACKETED.match(leaf) or _known_unit(unit, kind):
            return _Role(name, unit)
    return _Role(name, None)


# ---------------------------------------------------------------------------- file sources
@dataclass
class _Source:
    """Named numeric arrays of one file: shapes up front, values loaded on demand.

    ``shapes`` maps each field to its shape in the user's orientation (MATLAB v7.3 arrays
    already transposed back); ``load(names, text_ok)`` returns those fields as float arrays
    (a text column named in ``text_ok`` may come back as text);
    ``unit_attributes`` holds units stored beside the data (HDF5 ``units`` attributes);
    ``row_label(i)`` names data row ``i`` (zero-based) as the user sees it in the file.
    """

    shapes: dict[str, tuple[int, ...]]
    load: Callable[..., dict[str, np.ndarray]]
    row_label: Callable[[int], str]
    unit_attributes: dict[str, str] = field(default_factory=dict)


def _sample_label(index: int) -> str:
    return f"row {index + 1}"


def _array_source(arrays: dict[str, object]) -> _Source:
    """A source over arrays in memory: the numeric 1-D and 2-D ones (Nx1, 1xN as 1-D)."""
    fields = {}
    for name, value in arrays.items():
        array = np.asarray(value)
        if array.dtype.kind in "fiub" and array.ndim in (1, 2) and array.size:
            fields[name] = array.squeeze() if array.ndim == 2 and 1 in array.shape else array
    return _Source(
        shapes={name: array.shape for name, array in fields.items()},
        load=lambda names, text_ok=(): {name: np.asarray(fields[name], float) for name in names},
        row_label=_sample_label,
    )


def _flatten(tree: dict, prefix: str = "") -> dict[str, object]:
    flat: dict[str, object] = {}
    for key, value in tree.items():
        if key.startswith("__"):
            continue
        if isinstance(value, dict):
            flat.update(_flatten(value, f"{prefix}{key}/"))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def _open_npz(path: Path) -> _Source:
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except (ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(f"cannot read it as NPZ ({exc}); save plain numeric arrays") from exc
    return _array_source(arrays)


def _open_mat_v5(path: Path) -> _Source:
    from scipy import io as scipy_io

    try:
        contents = scipy_io.loadmat(path, simplify_cells=True)
    except NotImplementedError:
        return _open_hdf5(path, matlab=True)
    except Exception as exc:  # scipy raises many kinds on a corrupt or truncated file
        raise InputError(f"cannot read it as a MATLAB file ({exc!r})") from exc
    return _array_source(_flatten(contents))


def _open_hdf5(path: Path, matlab: bool = False) -> _Source:
    import h5py

    shapes: dict[str, tuple[int, ...]] = {}
    units: dict[str, str] = {}

    def visit(name, item):
        if not isinstance(item, h5py.Dataset) or name.startswith("#") or "/#" in name:
            return
        if item.dtype.kind not in "fiub" or item.ndim not in (1, 2) or item.size == 0:
            return
        if matlab and _attribute_text(item.attrs.get("MATLAB_class")) == "char":
            return
        shape = item.shape[::-1] if matlab else item.shape
        shapes[name] = (max(shape),) if len(shape) == 2 and 1 in shape else shape
        unit = _attribute_text(item.attrs.get("units", item.attrs.get("unit")))
        if unit:
            units[name] = unit

    try:
        with h5py.File(path, "r") as handle:
            handle.visititems(visit)
    except OSError as exc:
        raise InputError(f"cannot read it as HDF5 ({exc})") from exc

    def load(names, text_ok=()):
        with h5py.File(path, "r") as handle:
            arrays = {name: np.asarray(handle[name][()], dtype=float) for name in names}
        if matlab:
            arrays = {name: array.T for name, array in arrays.items()}
        return {name: array.reshape(shapes[name]) for name, array in arrays.items()}

    return _Source(shapes, load, _sample_label, units)


def _attribute_text(value) -> str | None:
    if value is None:
        return None
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray) and value.size == 1:
        return _attribute_text(value.item())
    return str(value)


def _open_parquet(path: Path) -> _Source:
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as exc:
        raise InputError("reading Parquet needs pyarrow: pip install 'wavemeter[parquet]'") from exc
    try:
        schema = pq.read_schema(path)
    except (pa.ArrowException, OSError) as exc:
        raise InputError(f"cannot read it as Parquet ({exc})") from exc
    rows = pq.ParquetFile(path).metadata.num_rows
    numeric = [
        schema_field.name
        for schema_field in schema
        if pa.types.is_floating(schema_field.type) or pa.types.is_integer(schema_field.type)
    ]

    def load(names, text_ok=()):
        table = pq.read_table(path, columns=names)
        return {
            name: np.asarray(table.column(name).cast(pa.float64()).fill_null(np.nan))
            for name in names
        }

    return _Source({name: (rows,) for name in numeric}, load, _sample_label)


# ---------------------------------------------------------------------------- text files
@dataclass(frozen=True)
class _TextLayout:
    encoding: str
    delimiter: str | None  # None: runs of whitespace
    names: list[str]
    header_line: int  # zero-based line index of the header
    data_offset: int | None  # byte offset of the first data line (None: not found)


def _decode(head: bytes) -> tuple[str, str]:
    try:
        return head.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError as exc:
        if exc.start >= len(head) - 3:  # a multi-byte character cut by the read size
            return head[: exc.start].decode("utf-8-sig"), "utf-8"
        return head.decode("latin-1"), "latin-1"


def _split(line: str, delimiter: str | None) -> list[str]:
    if delimiter is None:
        return line.split()
    return next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])


def _sniff_layout(path: Path) -> _TextLayout:
    with open(path, "rb") as handle:
        head = handle.read(_HEAD_BYTES)
        complete = not handle.read(1)
    if not head.strip():
        raise InputError("the file is empty")
    text, encoding = _decode(head)
    lines = text.splitlines()
    if not complete:
        lines = lines[:-1]  # the last line may be cut by the read size
    header_line = next(
        (i for i, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")),
        None,
    )
    if header_line is None:
        raise InputError("no header row: the file holds only comments or blank lines")
    sample = [line for line in lines[header_line + 1 : header_line + 6] if line.strip()]
    if not sample:
        raise InputError("the file has a header row but no data rows")
    header = lines[header_line]
    candidates = []  # (rows agreeing with the header, priority, delimiter, names)
    for priority, delimiter in enumerate(("\t", ",", ";", None)):
        names = _split(header, delimiter)
        if len(names) >= 2:
            widths = (len(_split(line, delimiter)) for line in sample)
            agreeing = sum(width in (len(names), len(names) + 1) for width in widths)
            candidates.append((agreeing, -priority, delimiter, names))
    if not candidates:
        raise InputError(
            "cannot tell the column delimiter (tried tab, comma, semicolon, spaces): the "
            "header row has a single column"
        )
    _, _, delimiter, names = max(candidates, key=lambda candidate: candidate[:2])
    offset = -1
    for _ in range(header_line + 1):
        offset = head.find(b"\n", offset + 1)
    data_offset = offset + 1 if offset >= 0 else None
    return _TextLayout(encoding, delimiter, _column_names(names), header_line, data_offset)


def _column_names(raw: list[str]) -> list[str]:
    names = [name.strip().strip('"').strip() or f"column {k + 1}" for k, name in enumerate(raw)]
    seen: dict[str, int] = {}
    for k, name in enumerate(names):
        if name in seen:
            raise InputError(
                f"duplicate column name {name!r} (columns {seen[name] + 1} and {k + 1}); "
                "rename one of them"
            )
        seen[name] = k
    return names


def _open_text(path: Path) -> _Source:
    layout = _sniff_layout(path)
    index = {name: k for k, name in enumerate(layout.names)}

    def load(names, text_ok=frozenset()):
        columns = [index[name] for name in names]
        data = _parse_text_with_arrow(path, layout, columns)
        if data is not None:
            return {name: data[:, k] for k, name in enumerate(names)}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
                data = np.loadtxt(
                    path,
                    delimiter=layout.delimiter,
                    skiprows=layout.header_line + 1,
                    usecols=columns,
                    comments=None,
                    quotechar='"',
                    encoding="latin-1",
                    ndmin=2,
                )
        except ValueError:
            return _parse_text_exactly(path, layout, names, set(text_ok))
        if data.shape[0] == 0:
            raise InputError("the file has a header row but no data rows")
        return {name: data[:, k] for k, name in enumerate(names)}

    def row_label(row: int) -> str:
        return f"line {_data_line_numbers(path, layout, row + 1)[row]}"

    # every column of a text file is 1-D; its length (-1 here) is known once read
    return _Source({name: (-1,) for name in layout.names}, load, row_label)


def _parse_text_with_arrow(path: Path, layout: _TextLayout, columns: list[int]):
    """Columns (N, k) parsed by pyarrow when it is installed (about 8x faster than numpy).

    Returns None when pyarrow is missing, the file is whitespace-delimited, or pyarrow
    cannot parse it; the numpy parsers then read the file and report what is wrong.
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
        with open(path, "rb") as handle:
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


def _data_lines(path: Path, layout: _TextLayout):
    """``(line_number, text)`` of each non-blank data line, line numbers 1-based."""
    with open(path, encoding=layout.encoding, errors="replace", newline="") as handle:
        for number, line in enumerate(handle, start=1):
            if number > layout.header_line + 1 and line.strip():
                yield number, line


def _data_line_numbers(path: Path, layout: _TextLayout, count: int) -> list[int]:
    numbers = []
    for number, _ in _data_lines(path, layout):
        numbers.append(number)
        if len(numbers) >= count:
            break
    return numbers


def _parse_text_exactly(
    path: Path, layout: _TextLayout, names: list[str], text_ok: set[str]
) -> dict[str, np.ndarray]:
    """Slow, exact parse: empty cells become NaN; a column in ``text_ok`` that is not all
    numbers comes back as text; any other cell that is not a number is an error."""
    width = len(layout.names)
    columns = [layout.names.index(name) for name in names]
    cells: list[list[str]] = [[] for _ in names]
    line_numbers = []
    for number, line in _data_lines(path, layout):
        fields = _split(line.rstrip("\r\n"), layout.delimiter)
        if len(fields) not in (width, width + 1):
            raise InputError(f"line {number} has {len(fields)} fields, the header has {width}")
        line_numbers.append(number)
        for k, column in enumerate(columns):
            cells[k].append(fields[column].strip())
    return {
        name: _numbers(name, values, name in text_ok, line_numbers)
        for name, values in zip(names, cells, strict=True)
    }


def _numbers(name: str, cells: list[str], text_ok: bool, line_numbers: list[int]) -> np.ndarray:
    """A column of cells as float64 (empty cells NaN), or as text when allowed."""
    values = np.empty(len(cells))
    for row, cell in enumerate(cells):
        try:
            values[row] = float(cell) if cell else np.nan
        except ValueError:
            if text_ok:
                return np.array(cells, dtype=str)
            hint = (
                " (a decimal comma? write decimal points)"
                if re.fullmatch(r"[-+]?\d+,\d+", cell)
                else ""
            )
            raise InputError(
                f"line {line_numbers[row]}, column {name!r}: {cell!r} is not a number{hint}"
            ) from None
    return values


# ---------------------------------------------------------------------------- format dispatch
def _file_kind(path: Path) -> str:
    with open(path, "rb") as handle:
        head = handle.read(1024)
    if head.startswith(b"\x89HDF") or head[512:516] == b"\x89HDF":
        return "mat73" if path.suffix.lower() == ".mat" else "hdf5"
    if head.startswith(b"MATLAB 5.0") or path.suffix.lower() == ".mat":
        return "mat"
    if head.startswith(b"PK\x03\x04"):
        return "npz"
    if head.startswith(b"PAR1"):
        return "parquet"
    return "text"


def _open(path: Path) -> _Source:
    if not path.exists():
        raise InputError("file not found")
    if path.is_dir():
        raise InputError("is a folder, not a data file")
    kind = _file_kind(path)
    if kind == "text":
        return _open_text(path)
    if kind == "npz":
        return _open_npz(path)
    if kind == "mat":
        return _open_mat_v5(path)
    if kind == "mat73":
        return _open_hdf5(path, matlab=True)
    if kind == "hdf5":
        return _open_hdf5(path)
    return _open_parquet(path)


# ---------------------------------------------------------------------------- the table
@dataclass(frozen=True)
class ColumnRequest:
    """Which columns to use and their units; ``None`` means find them by name.

    Parameters
    ----------
    x : str, optional
        Column with the known frequency (sweep) or true frequency (test), or its wavelength.
    x_unit : str, optional
        Unit of ``x`` (Hz..THz, nm, um, m), overriding the unit in its name.
    ports : sequence of str, optional
        Port columns in order; a 2-D array counts as one port per row or column.
    power_unit : str, optional
        Unit of the port columns (W, mW, uW, nW, dBm, V), overriding their names.
    monitor : str, optional
        Source-power monitor column.
    temperature : str, optional
        Temperature column (K or C).
    coarse : str, optional
        Column with a coarse frequency (or wavelength) per reading, for calibration sets.
    keep : sequence of str
        Further columns to carry through unchanged (e.g. a time stamp).
    """

    x: str | None = None
    x_unit: str | None = None
    ports: Sequence[str] | None = None
    power_unit: str | None = None
    monitor: str | None = None
    temperature: str | None = None
    coarse: str | None = None
    keep: Sequence[str] = ()


@dataclass(frozen=True)
class Table:
    """Readings from one file, in SI units, one row per data row of the file.

    Attributes
    ----------
    source : Path
        The file read.
    powers_w : ndarray, shape (N, n)
        Port readings (W; for ``V`` or unlabelled ports, the values as written).
    port_names : tuple of str, length n
        Port column names as in the file (a 2-D array ``P`` gives ``P1, P2, ...``).
    port_units : tuple of str, length n
        Unit each port was read in; ``""`` when the name carries none (relative).
    x_hz : ndarray, shape (N,), or None
        Known (sweep) or true (test) frequency (Hz); None when the file has none.
    x_column, x_unit : str or None
        The axis column and the unit it was read in.
    monitor_w, temperature_k, coarse_hz : ndarray, shape (N,), or None
        Power monitor (W or relative), temperature (K), coarse frequency (Hz).
    monitor_column, temperature_column, coarse_column : str or None
        Their column names.
    kept : dict of str to ndarray, shape (N,)
        Columns asked for with ``keep``, as read.
    invalid_code : ndarray of int, shape (N,)
        -1 for a valid row, else the index in ``invalid_reasons`` of its first problem
        (NaN/inf, power-meter sentinel, no light, bad monitor reading).
    invalid_reasons : tuple of str
        Text of each problem found.
    row_index : ndarray of int, shape (N,)
        Zero-based index of each row among the file's data rows.
    rows_in_file : int
        Number of data rows in the file.
    """

    source: Path
    powers_w: np.ndarray
    port_names: tuple[str, ...]
    port_units: tuple[str, ...]
    invalid_code: np.ndarray
    row_index: np.ndarray
    rows_in_file: int
    row_label: Callable[[int], str]
    x_hz: np.ndarray | None = None
    x_column: str | None = None
    x_unit: str | None = None
    monitor_w: np.ndarray | None = None
    monitor_column: str | None = None
    temperature_k: np.ndarray | None = None
    temperature_column: str | None = None
    coarse_hz: np.ndarray | None = None
    coarse_column: str | None = None
    kept: dict[str, np.ndarray] = field(default_factory=dict)
    invalid_reasons: tuple[str, ...] = ()

    @property
    def invalid(self) -> np.ndarray:
        """Boolean mask (N,) of the invalid rows."""
        return self.invalid_code >= 0

    @property
    def n_rows(self) -> int:
        """Number of rows N."""
        return self.powers_w.shape[0]

    @property
    def dropped_rows(self) -> int:
        """Data rows of the file not in this table (skipped as invalid)."""
        return self.rows_in_file - self.n_rows

    def select(self, rows) -> Table:
        """A table of the given rows (boolean mask or indices), in that order."""

        def take(values):
            return None if values is None else values[rows]

        return dataclasses.replace(
            self,
            powers_w=self.powers_w[rows],
            invalid_code=self.invalid_code[rows],
            row_index=self.row_index[rows],
            x_hz=take(self.x_hz),
            monitor_w=take(self.monitor_w),
            temperature_k=take(self.temperature_k),
            coarse_hz=take(self.coarse_hz),
            kept={name: values[rows] for name, values in self.kept.items()},
        )

    def valid_only(self) -> Table:
        """The table without its invalid rows."""
        return self.select(~self.invalid)

    def describe_invalid(self, limit: int = 5) -> str:
        """The first invalid rows with their reasons, e.g. ``line 5 (P2_mW is NaN)``."""
        rows = np.flatnonzero(self.invalid)[:limit]
        return ", ".join(
            f"{self.row_label(int(self.row_index[k]))} "
            f"({self.invalid_reasons[self.invalid_code[k]]})"
            for k in rows
        )


def _single(candidates: list[_Role], what: str, option: str) -> _Role | None:
    if len(candidates) > 1:
        names = ", ".join(repr(role.name) for role in candidates)
        raise InputError(f"columns {names} all look like the {what}; choose one with {option}")
    return candidates[0] if candidates else None


def _require(source: _Source, name: str, option: str) -> None:
    if name not in source.shapes:
        available = ", ".join(repr(n) for n in source.shapes) or "none"
        raise InputError(f"no column {name!r} (given by {option}); columns: {available}")


def _find_roles(
    source: _Source, request: ColumnRequest, need_x: bool, find_extras: bool
) -> dict[str, object]:
    """Resolve every role to columns: explicit requests first, else by name."""
    names = list(source.shapes)
    for option, name in (
        ("--x", request.x),
        ("--monitor", request.monitor),
        ("--temperature", request.temperature),
        ("--coarse", request.coarse),
        *(("--ports", port) for port in request.ports or ()),
        *(("--keep", kept) for kept in request.keep),
    ):
        if name is not None:
            _require(source, name, option)

    def one_dimensional(pattern):
        found = [_match_role(name, pattern) for name in names if len(source.shapes[name]) == 1]
        return [role for role in found if role is not None]

    x_role = None
    if request.x is not None:
        x_role = _explicit_role(request.x, "axis", request.x_unit)
    elif need_x:
        x_role = _single(one_dimensional(_X_ROLE), "frequency axis", "--x")
        if x_role is not None and request.x_unit is not None:
            x_role = dataclasses.replace(x_role, unit=request.x_unit)
    if need_x and x_role is None:
        raise InputError(
            "no frequency or wavelength column (looked for names like frequency_hz, "
            f"freq_THz, wavelength_nm, 'Wavelength (nm)'); columns: {', '.join(names)}; "
            "name the column or pass --x COLUMN"
        )
    monitor = temperature = None
    if request.monitor is not None:
        monitor = _explicit_role(request.monitor, "power", None)
    elif find_extras:
        monitor = _single(one_dimensional(_MONITOR_ROLE), "power monitor", "--monitor")
    if monitor is not None and monitor.unit is None and request.power_unit is not None:
        monitor = dataclasses.replace(monitor, unit=request.power_unit)
    if request.temperature is not None:
        temperature = _explicit_role(request.temperature, "temperature", None)
    elif find_extras:
        found = _single(one_dimensional(_TEMPERATURE_ROLE), "temperature", "--temperature")
        has_unit = found is not None and (found.unit or source.unit_attributes.get(found.name))
        temperature = found if has_unit else None
    coarse = None if request.coarse is None else _explicit_role(request.coarse, "axis", None)
    return {
        "x": x_role,
        "ports": _find_ports(source, request, names),
        "monitor": monitor,
        "temperature": temperature,
        "coarse": coarse,
    }


def _find_ports(source: _Source, request: ColumnRequest, names: list[str]) -> list[_Role]:
    if request.ports is not None:
        roles = [_explicit_role(name, "power", request.power_unit) for name in request.ports]
        if len(set(request.ports)) != len(request.ports):
            raise InputError(f"--ports names a column twice: {', '.join(request.ports)}")
    else:
        singles = [
            role
            for role in (_match_role(name, _PORT_ROLE) for name in names)
            if role is not None and len(source.shapes[role.name]) == 1
        ]
        roles = sorted(singles, key=lambda role: role.order)
        numbers = [(role.family, role.order) for role in roles]
        if len(set(numbers)) != len(numbers):
            listed = ", ".join(repr(role.name) for role in roles)
            raise InputError(
                f"port columns {listed} repeat a port number; choose them with --ports A,B,C"
            )
        if not roles:
            matrices = [
                role
                for role in (_match_role(name, _PORT_MATRIX_ROLE) for name in names)
                if role is not None and len(source.shapes[role.name]) == 2
            ]
            roles = [m for m in [_single(matrices, "port array", "--ports")] if m is not None]
        if request.power_unit is not None:
            roles = [dataclasses.replace(role, unit=request.power_unit) for role in roles]
    if not roles:
        raise InputError(
            "no port columns (looked for names like P1_mW, port2_dBm, 'Port 3 [uW]', "
            f"'DC CH1', p4); columns: {', '.join(names)}; name them or pass --ports A,B,C"
        )
    return roles


def _orient(array: np.ndarray, name: str, samples: int | None) -> np.ndarray:
    """A 2-D port array as (samples, ports): the axis whose length is ``samples``."""
    rows, cols = array.shape
    if samples is not None:
        if rows == samples and cols == samples:
            raise InputError(
                f"cannot tell samples from ports in {name!r} of shape {array.shape}: both axes "
                f"have {samples} entries"
            )
        if rows == samples:
            return array
        if cols == samples:
            return array.T
        raise InputError(
            f"{name!r} has shape {array.shape} but the other columns have {samples} samples"
        )
    if cols <= MAX_PORTS < rows:
        return array
    if rows <= MAX_PORTS < cols:
        return array.T
    raise InputError(
        f"cannot tell samples from ports in {name!r} of shape {array.shape}; store the "
        "frequency vector beside it or use more samples than ports"
    )


def _sample_count(source: _Source, data: dict[str, np.ndarray]) -> int | None:
    """Samples N from the 1-D columns read (or, failing that, from all 1-D fields)."""
    lengths = {len(values) for values in data.values() if values.ndim == 1}
    if not lengths:
        lengths = {shape[0] for shape in source.shapes.values() if len(shape) == 1}
    if len(lengths) > 1:
        shown = ", ".join(f"{name!r} ({len(v)})" for name, v in data.items() if v.ndim == 1)
        raise InputError(f"columns have different lengths: {shown}")
    return lengths.pop() if lengths else None


def _axis_hz(role: _Role, values: np.ndarray) -> tuple[np.ndarray, str]:
    """Axis in Hz and the unit used; without a unit, the one unit that makes it optical."""
    if role.unit is not None:
        return axis_to_hz(values, role.unit, role.name), canonical_unit(role.unit, "axis")
    leaf = role.name.rsplit("/", 1)[-1]
    units = WAVELENGTH_UNITS if _WAVELENGTH_WORD.search(leaf.lower()) else FREQUENCY_UNITS
    for unit in units:
        try:
            return axis_to_hz(values, unit, role.name), unit
        except ValueError:
            continue
    raise InputError(
        f"column {role.name!r} has no unit and its values are not optical in any "
        f"{'wavelength' if units is WAVELENGTH_UNITS else 'frequency'} unit; name it like "
        "frequency_hz or wavelength_nm, or pass --x-unit"
    )


def _power_unit(role: _Role, source: _Source) -> str:
    unit = role.unit if role.unit is not None else source.unit_attributes.get(role.name)
    if unit is None:
        return ""
    return canonical_unit(unit, "power", f"column {role.name!r}")


def _raw_power_problems(raw: np.ndarray, unit: str) -> tuple[np.ndarray, np.ndarray]:
    """Masks of (non-finite, sentinel) raw readings."""
    nonfinite = ~np.isfinite(raw)
    sentinel = raw > SENTINEL_W
    if unit == "dBm":
        sentinel |= raw <= SENTINEL_DBM
    return nonfinite, sentinel


def _check_linear_column(name: str, raw: np.ndarray, unit: str) -> None:
    finite = raw[np.isfinite(raw) & (raw < SENTINEL_W)]
    if unit != "dBm" and finite.size and np.all(finite <= 0):
        raise InputError(
            f"column {name!r}{f' (labelled {unit})' if unit else ''} has no positive reading: "
            "are these dBm? pass --power-unit dBm"
        )


class _Invalid:
    """Collects per-row problems: a mask and the first reason for each bad row."""

    def __init__(self, rows: int):
        self.mask = np.zeros(rows, dtype=bool)
        self.reason = np.full(rows, -1)
        self.reasons: list[str] = []

    def add(self, mask: np.ndarray, reason: str) -> None:
        fresh = mask & ~self.mask
        if fresh.any():
            self.reason[fresh] = len(self.reasons)
            self.reasons.append(reason)
            self.mask |= mask


def _ports_array(roles, data, samples, source, invalid: _Invalid):
    """Port readings (N, n) in W with names and units; flags bad readings in ``invalid``."""
    columns, names, units = [], [], []
    for role in roles:
        values = data[role.name]
        unit = _power_unit(role, source)
        if values.ndim == 2:
            block = _orient(values, role.name, samples)
            leaf = role.name.rsplit("/", 1)[-1]
            base, unit_token = split_unit(leaf)[-1]
            if unit_token is not None and not _known_unit(unit_token, "power"):
                base = leaf
            parts = [(f"{base}{k + 1}", block[:, k]) for k in range(block.shape[1])]
        else:
            parts = [(role.name, values)]
        for name, raw in parts:
            _check_linear_column(name, raw, unit)
            nonfinite, sentinel = _raw_power_problems(raw, unit)
            invalid.add(nonfinite, f"{name} is NaN, empty or inf")
            code = _first(raw, sentinel)
            invalid.add(sentinel, f"{name} is a power-meter 'no reading' code {code}")
            columns.append(power_to_w(raw, unit or "W", name))
            names.append(name)
            units.append(unit)
    powers = np.column_stack(columns)
    with np.errstate(invalid="ignore", over="ignore"):
        invalid.add(~(powers.sum(axis=1) > 0), "port powers sum to <= 0: no light")
    return powers, tuple(names), tuple(units)


def _first(raw: np.ndarray, mask: np.ndarray) -> str:
    return f"{raw[mask][0]:g}" if mask.any() else ""


def read_table(
    path,
    request: ColumnRequest | None = None,
    *,
    need_x: bool = True,
    find_extras: bool = True,
    allow_invalid: bool = False,
) -> Table:
    """Read readings from a data file, find the columns by name and convert to SI.

    Parameters
    ----------
    path : str or Path
        CSV/TSV (header row; delimiter sniffed), HDF5, MAT (v5 or v7.3), NPZ or Parquet.
    request : ColumnRequest, optional
        Columns and units chosen by the user; anything left None is found by name.
    need_x : bool
        Whether a frequency/wavelength column must exist (calibration sweeps, test files).
    find_extras : bool
        Look for a power monitor and a temperature column by name. A temperature found
        by name without a unit is left out; one named in ``request`` must have a unit.
    allow_invalid : bool
        Keep invalid rows (flagged in ``Table.invalid``) instead of raising.

    Returns
    -------
    Table

    Raises
    ------
    ValueError
        For a missing, empty or unreadable file, missing, duplicate or ambiguous columns,
        unknown units, non-numeric cells, implausible values, and (unless
        ``allow_invalid``) invalid rows. The message starts with the file name.
    """
    path = Path(path)
    request = request or ColumnRequest()
    try:
        return _read(path, request, need_x, find_extras, allow_invalid)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from exc
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from exc


def _read(
    path: Path, request: ColumnRequest, need_x: bool, find_extras: bool, allow_invalid: bool
) -> Table:
    source = _open(path)
    roles = _find_roles(source, request, need_x, find_extras)
    single = {key: roles[key] for key in ("x", "monitor", "temperature", "coarse")}
    wanted = [role.name for role in single.values() if role is not None]
    wanted += [role.name for role in roles["ports"]] + list(request.keep)
    data = source.load(list(dict.fromkeys(wanted)), text_ok=set(request.keep))
    for name in request.keep:
        if data[name].ndim != 1:
            raise InputError(
                f"--keep column {name!r} must be a vector, has shape {data[name].shape}"
            )
    rows = _sample_count(source, data)
    if rows is None:
        first = roles["ports"][0].name
        rows = _orient(data[first], first, None).shape[0]
    invalid = _Invalid(rows)
    powers, port_names, port_units = _ports_array(roles["ports"], data, rows, source, invalid)
    if powers.shape[1] < 3:
        raise InputError(
            f"found {powers.shape[1]} port column(s) ({', '.join(port_names)}); need at least 3"
        )
    fields: dict[str, object] = {}
    for key in ("x", "coarse"):
        role = single[key]
        if role is not None:
            raw = data[role.name]
            invalid.add(~np.isfinite(raw), f"{role.name} is NaN, empty or inf")
            fields[f"{key}_hz"], unit = _axis_hz(role, raw)
            fields[f"{key}_column"] = role.name
            if key == "x":
                fields["x_unit"] = unit
    monitor = single["monitor"]
    if monitor is not None:
        raw = data[monitor.name]
        unit = _power_unit(monitor, source)
        nonfinite, sentinel = _raw_power_problems(raw, unit)
        invalid.add(nonfinite | sentinel, f"{monitor.name} is NaN, inf or a 'no reading' code")
        fields["monitor_w"] = power_to_w(raw, unit or "W", monitor.name)
        with np.errstate(invalid="ignore"):
            invalid.add(~(fields["monitor_w"] > 0), f"{monitor.name} is <= 0")
        fields["monitor_column"] = monitor.name
    temperature = single["temperature"]
    if temperature is not None:
        raw = data[temperature.name]
        unit = temperature.unit or source.unit_attributes.get(temperature.name)
        if unit is None:
            raise InputError(
                f"temperature column {temperature.name!r} has no unit; name it like "
                "temperature_K or 'Temperature (C)'"
            )
        invalid.add(~np.isfinite(raw), f"{temperature.name} is NaN, empty or inf")
        fields["temperature_k"] = temperature_to_k(raw, unit, temperature.name)
        fields["temperature_column"] = temperature.name
    table = Table(
        source=path,
        powers_w=powers,
        port_names=port_names,
        port_units=port_units,
        invalid_code=invalid.reason,
        invalid_reasons=tuple(invalid.reasons),
        row_index=np.arange(rows),
        rows_in_file=rows,
        row_label=source.row_label,
        kept={name: data[name] for name in request.keep},
        **fields,
    )
    if table.invalid.any() and not allow_invalid:
        raise InputError(
            f"{int(table.invalid.sum())} invalid row(s): {table.describe_invalid()}; fix or "
            "delete them, or pass --drop-invalid to skip them"
        )
    return table


# ---------------------------------------------------------------------------- writing
def table_format(path, file_format: str | None = None) -> str:
    """Output format: ``file_format`` if given, else from the file extension (default CSV)."""
    if file_format is not None:
        if file_format not in FORMATS:
            raise InputError(f"format must be one of {', '.join(FORMATS)}; got {file_format!r}")
        return file_format
    found = _EXTENSIONS.get(Path(path).suffix.lower(), "csv")
    if found == "mat":
        raise InputError(f"{path}: cannot write MAT files; write one of {', '.join(FORMATS)}")
    return found


def write_table(path, columns: dict[str, np.ndarray], file_format: str | None = None) -> None:
    """Write named 1-D columns to a file, atomically, floats at full float64 precision.

    Parameters
    ----------
    path : str or Path
        Output file.
    columns : dict of str to array_like, each shape (N,)
        Column name (with its unit suffix, e.g. ``frequency_hz``) to values: numbers, or
        text (kept columns of a text file).
    file_format : {"csv", "tsv", "parquet", "hdf5", "npz"}, optional
        Default: from the extension of ``path`` (``.parquet``, ``.h5``, ``.npz``, ``.tsv``),
        else CSV. CSV floats are the shortest text that reads back to the same float64.
    """
    kind = table_format(path, file_format)
    arrays = {name: _column_array(values) for name, values in columns.items()}
    lengths = {len(values) for values in arrays.values()}
    if len(lengths) > 1:
        raise InputError(f"columns to write have different lengths: {sorted(lengths)}")
    writer = {
        "csv": _write_text,
        "tsv": _write_text,
        "parquet": _write_parquet,
        "hdf5": _write_hdf5,
        "npz": _write_npz,
    }[kind]
    if kind == "parquet":
        _require_pyarrow()
    with atomic_path(path) as temporary:
        writer(temporary, arrays, "\t" if kind == "tsv" else ",")


def _column_array(values) -> np.ndarray:
    array = np.asarray(values)
    if array.ndim != 1:
        raise InputError(f"columns to write must be 1-D, got shape {array.shape}")
    if array.dtype.kind in "fiub":
        return array.astype(float)
    return array.astype(str)


def _text_cells(values: np.ndarray, delimiter: str) -> list[str]:
    if values.dtype.kind == "f":
        return list(map(repr, values.tolist()))
    return [_quoted(cell, delimiter) for cell in values.tolist()]


def _quoted(cell: str, delimiter: str) -> str:
    if delimiter in cell or '"' in cell or "\n" in cell:
        return '"' + cell.replace('"', '""') + '"'
    return cell


def _write_text(path: Path, arrays: dict[str, np.ndarray], delimiter: str) -> None:
    rows = len(next(iter(arrays.values()))) if arrays else 0
    with open(path, "w", encoding="utf-8", newline="\n") as handle:
        handle.write(delimiter.join(_quoted(name, delimiter) for name in arrays) + "\n")
        for start in range(0, rows, _CSV_CHUNK_ROWS):
            block = [
                _text_cells(values[start : start + _CSV_CHUNK_ROWS], delimiter)
                for values in arrays.values()
            ]
            handle.write("\n".join(map(delimiter.join, zip(*block, strict=True))) + "\n")


def _require_pyarrow():
    try:
        import pyarrow  # noqa: F401
    except ImportError as exc:
        raise InputError("writing Parquet needs pyarrow: pip install 'wavemeter[parquet]'") from exc


def _write_parquet(path: Path, arrays: dict[str, np.ndarray], _delimiter: str) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({name: pa.array(values) for name, values in arrays.items()}), path)


def _write_hdf5(path: Path, arrays: dict[str, np.ndarray], _delimiter: str) -> None:
    import h5py

    with h5py.File(path, "w") as handle:
        for name, values in arrays.items():
            if values.dtype.kind == "U":
                handle.create_dataset(name, data=values.astype(object), dtype=h5py.string_dtype())
            else:
                handle.create_dataset(name, data=values)


def _write_npz(path: Path, arrays: dict[str, np.ndarray], _delimiter: str) -> None:
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)
