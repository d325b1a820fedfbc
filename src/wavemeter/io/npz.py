"""NumPy ``.npz`` archives: reading and writing.

Only the ``.npy`` headers are read to list the fields; a member's values are decompressed
only when that field is used, after its declared size has been checked against the size
limit and against the member's size in the archive (an unused 3 GB member of a 3 MB archive
is never expanded). Object arrays (pickles) are refused. Written member names are made safe
for any unzip tool: no folders, no leading dot, no control characters.

Chunks are read from the members' streams (stored or deflated alike) when the samples of
every field used lie one after the other (1-D arrays, C-ordered 2-D arrays with the
samples along the first axis, Fortran-ordered ones with them along the second); otherwise
the fields are read whole and cut into chunks. :class:`NPZChunkWriter` writes each column's
chunks to a temporary file beside the output and assembles the archive from them at the
end, so the memory it takes is one chunk.
"""

from __future__ import annotations

import math
import re
import shutil
import struct
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..exceptions import FileFormatError, InputError
from .source import (
    Chunk,
    RawInput,
    Source,
    check_allocation,
    library_errors,
    sample_label,
    whole_chunks,
)

__all__ = ["read_npz", "write_npz", "member_name", "NPZChunkWriter"]

#: what zipfile, zlib and numpy's .npy parser raise on a damaged archive or member
_ARCHIVE_ERRORS = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    OSError,
    ValueError,
    struct.error,
    NotImplementedError,  # a compression method zipfile does not know
    RuntimeError,  # an encrypted member
    UnicodeDecodeError,
)
_HEADER_LIMIT = 10_000  # numpy's own limit on a .npy header (bytes)


def _read_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo):
    """``(shape, dtype, header bytes)`` of a ``.npy`` member, from its first bytes only."""
    with archive.open(info) as member:
        version = np.lib.format.read_magic(member)
        if version == (1, 0):
            header = np.lib.format.read_array_header_1_0(member, max_header_size=_HEADER_LIMIT)
        elif version == (2, 0):
            header = np.lib.format.read_array_header_2_0(member, max_header_size=_HEADER_LIMIT)
        else:
            raise FileFormatError(
                f"member {info.filename!r} is a .npy file of version {version}; save it with "
                "numpy.savez (versions 1.0 and 2.0 are read)"
            )
        shape, fortran_order, dtype = header
        return tuple(shape), dtype, member.tell(), fortran_order


def read_npz(raw: RawInput, max_bytes: int) -> Source:
    """The numeric 1-D and 2-D arrays of an NPZ archive, decompressed only when used."""
    members: dict[str, zipfile.ZipInfo] = {}
    shapes: dict[str, tuple[int, ...]] = {}
    layouts: dict[str, tuple[tuple[int, ...], np.dtype, bool]] = {}  # as stored
    with library_errors("NPZ", _ARCHIVE_ERRORS), zipfile.ZipFile(raw.open()) as archive:
        for info in archive.infolist():
            if not info.filename.endswith(".npy") or info.is_dir():
                continue
            name = info.filename[: -len(".npy")]
            shape, dtype, header_bytes, fortran_order = _read_header(archive, info)
            if dtype.hasobject:
                raise FileFormatError(
                    f"member {name!r} holds Python objects (a pickle), which are never loaded: "
                    "save plain numeric arrays"
                )
            cells = math.prod(shape)
            if header_bytes + cells * dtype.itemsize > info.file_size:
                raise FileFormatError(
                    f"member {name!r} declares shape {shape} of {dtype} but holds only "
                    f"{info.file_size} bytes: it is damaged"
                )
            if dtype.kind in "fiub" and len(shape) in (1, 2) and cells:
                members[name] = info
                shapes[name] = (max(shape),) if len(shape) == 2 and 1 in shape else shape
                layouts[name] = (shape, dtype, fortran_order)

    def load(names, text_ok=()):
        cells = sum(math.prod(shapes[name]) for name in names)
        check_allocation(f"the members {names}", 8 * cells, max_bytes)
        arrays = {}
        with library_errors("NPZ", _ARCHIVE_ERRORS), zipfile.ZipFile(raw.open()) as archive:
            for name in names:
                with archive.open(members[name]) as member:
                    array = np.lib.format.read_array(
                        member, allow_pickle=False, max_header_size=_HEADER_LIMIT
                    )
                arrays[name] = np.asarray(array, dtype=float).reshape(shapes[name])
        return arrays

    def chunks(names, chunk_rows, sample_axes=None, text_ok=()) -> Iterator[Chunk]:
        sample_axes = sample_axes or {}
        if not all(_in_row_order(layouts[name], sample_axes.get(name)) for name in names):
            yield from whole_chunks(source, names, chunk_rows, sample_axes, text_ok)
            return
        check_allocation(
            f"{len(names)} members of {chunk_rows} rows", 8 * chunk_rows * len(names), max_bytes
        )
        total = {_samples(shapes[name], sample_axes.get(name)) for name in names}
        if len(total) > 1:
            raise FileFormatError(f"the members {list(names)} have different lengths")
        rows = total.pop() if total else 0
        with library_errors("NPZ", _ARCHIVE_ERRORS), zipfile.ZipFile(raw.open()) as archive:
            streams = {}
            try:
                for name in names:
                    streams[name] = archive.open(members[name])
                    _skip_header(streams[name])
                for start in range(0, rows, chunk_rows):
                    stop = min(start + chunk_rows, rows)
                    columns = {
                        name: _member_rows(streams[name], layouts[name], stop - start, name)
                        for name in names
                    }
                    yield Chunk(start, columns, sample_label)
            finally:
                for stream in streams.values():
                    stream.close()

    source = Source(shapes, load, chunks=chunks)
    return source


def _samples(shape: tuple[int, ...], sample_axis: int | None) -> int:
    return shape[0] if sample_axis is None else shape[sample_axis]


def _in_row_order(layout, sample_axis: int | None) -> bool:
    """Whether a member's samples lie one after the other (each sample's values together)."""
    shape, _, fortran_order = layout
    if len(shape) == 1 or 1 in shape:
        return True
    return (sample_axis == 0) != fortran_order


def _skip_header(stream) -> None:
    """Read a ``.npy`` member's magic and header, leaving ``stream`` at its first value."""
    version = np.lib.format.read_magic(stream)
    if version == (1, 0):
        np.lib.format.read_array_header_1_0(stream, max_header_size=_HEADER_LIMIT)
    else:
        np.lib.format.read_array_header_2_0(stream, max_header_size=_HEADER_LIMIT)


def _member_rows(stream, layout, count: int, name: str) -> np.ndarray:
    """The next ``count`` samples of a member's stream, float64, samples first."""
    shape, dtype, fortran_order = layout
    width = 1
    if len(shape) == 2 and 1 not in shape:
        width = shape[0] if fortran_order else shape[1]
    wanted = count * width * dtype.itemsize
    data = stream.read(wanted)
    if len(data) != wanted:
        raise FileFormatError(f"member {name!r} holds fewer values than it declares: damaged")
    values = np.frombuffer(data, dtype=dtype).astype(float)
    return values if width == 1 else values.reshape(count, width)


_UNSAFE = re.compile(r"[\x00-\x1f\x7f/\\:]")


def member_name(column: str) -> str:
    """A safe archive member name for a column (without ``.npy``): folder separators,
    drive colons and control characters become ``_``, a leading dot gets a ``_`` before it
    (``../../x`` -> ``_.._.._x``)."""
    safe = _UNSAFE.sub("_", column)
    return "_" + safe if not safe or safe.startswith(".") else safe


def _member_names(columns) -> dict[str, str]:
    """Each column's archive member name; two columns may not share one."""
    names = {column: member_name(column) for column in columns}
    seen: dict[str, str] = {}
    for column, safe in names.items():
        if safe in seen:
            raise InputError(
                f"columns {seen[safe]!r} and {column!r} both become NPZ member {safe!r} "
                "(folder separators and control characters are replaced): rename one"
            )
        seen[safe] = column
    return names


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write 1-D columns as an uncompressed NPZ (like ``numpy.savez``), one member each."""
    names = _member_names(arrays)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as archive:
        for column, values in arrays.items():
            with archive.open(f"{names[column]}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, values, allow_pickle=False)


_COPY_BYTES = 1 << 20


class NPZChunkWriter:
    """Writes 1-D columns to an uncompressed NPZ one chunk at a time, like :func:`write_npz`
    once complete.

    An archive member holds one column whole, so each column's chunks go to a raw file in a
    hidden temporary folder beside ``path`` (disk, not memory: one chunk is held at a
    time); :meth:`close` copies them into the archive and removes the folder, as
    :meth:`abort` does on failure. Text columns take the width of their longest cell.

    Parameters
    ----------
    path : Path
        The file to write (a temporary file; the caller renames it).
    """

    def __init__(self, path: Path):
        self._path = Path(path)
        self._folder = Path(
            tempfile.mkdtemp(prefix=f".{self._path.name}.", suffix=".parts", dir=self._path.parent)
        )
        self._columns: dict[str, dict] = {}

    def write(self, arrays: dict[str, np.ndarray]) -> None:
        """Append rows: 1-D columns (float64, int64 or text) of one length, the same
        columns at every call."""
        if not self._columns:
            names = _member_names(arrays)
            for k, column in enumerate(arrays):
                self._columns[column] = {
                    "member": names[column],
                    "file": open(self._folder / f"{k}.raw", "wb"),  # noqa: SIM115 - closed in close
                    "dtype": arrays[column].dtype,
                    "rows": 0,
                    "blocks": [],  # text: (rows, width) of each chunk
                }
        for column, values in arrays.items():
            record = self._columns[column]
            if values.dtype.kind == "U":
                width = max(values.dtype.itemsize // 4, 1)
                record["blocks"].append((len(values), width))
                record["file"].write(values.astype(f"<U{width}").tobytes())
            else:
                record["file"].write(np.ascontiguousarray(values, record["dtype"]).tobytes())
            record["rows"] += len(values)

    def close(self) -> None:
        """Assemble the archive from the columns' files, then remove them."""
        try:
            with zipfile.ZipFile(
                self._path, "w", compression=zipfile.ZIP_STORED, allowZip64=True
            ) as archive:
                for record in self._columns.values():
                    record["file"].close()
                    with archive.open(f"{record['member']}.npy", "w", force_zip64=True) as member:
                        self._copy(record, member)
        finally:
            self.abort()

    def _copy(self, record: dict, member) -> None:
        text = record["dtype"].kind == "U"
        widest = max((width for _, width in record["blocks"]), default=1)
        dtype = np.dtype(f"<U{widest}") if text else record["dtype"]
        header = {
            "descr": np.lib.format.dtype_to_descr(dtype),
            "fortran_order": False,
            "shape": (record["rows"],),
        }
        np.lib.format.write_array_header_1_0(member, header)
        with open(record["file"].name, "rb") as values:
            if not text:
                shutil.copyfileobj(values, member, _COPY_BYTES)
                return
            for rows, width in record["blocks"]:
                block = np.frombuffer(values.read(rows * width * 4), dtype=f"<U{width}")
                member.write(block.astype(dtype).tobytes())

    def abort(self) -> None:
        """Remove the columns' files (the archive is the caller's to remove)."""
        for record in self._columns.values():
            record["file"].close()
        shutil.rmtree(self._folder, ignore_errors=True)
