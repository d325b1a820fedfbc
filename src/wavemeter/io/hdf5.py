"""HDF5 files (and MATLAB v7.3 files, which are HDF5): reading and writing.

Numeric 1-D and 2-D datasets anywhere in the group tree are fields named by their path
(``scan/frequency``); a ``units`` (or ``unit``) attribute gives their unit. Only objects
reached through hard links are read: soft and external links are not followed, and
datasets whose values live outside the file (external raw storage, virtual datasets) are
refused. A dataset's declared size is checked against the size limit and, for contiguous
uncompressed storage, against the file's size before it is read; any error of the HDF5
library on a damaged file becomes a :class:`~wavemeter.exceptions.FileFormatError`.
Chunks of an HDF5 file are dataset slices along the samples (a MATLAB v7.3 file is read
whole); :class:`HDF5ChunkWriter` appends chunks to resizable datasets.
h5py is imported when a file is read or written.
"""

from __future__ import annotations

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
    library_reason,
    sample_label,
)

__all__ = ["read_hdf5", "read_mat73", "write_hdf5", "HDF5ChunkWriter"]

#: what h5py raises on a damaged or foreign file (HDF5 library errors map to these)
_H5PY_ERRORS = (OSError, KeyError, ValueError, RuntimeError, TypeError, IndexError)


def read_hdf5(raw: RawInput, max_bytes: int) -> Source:
    """The numeric 1-D and 2-D datasets of an HDF5 file, read on demand."""
    return _read(raw, max_bytes, matlab=False)


def read_mat73(raw: RawInput, max_bytes: int) -> Source:
    """The numeric arrays of a MATLAB v7.3 file (HDF5), transposed back to MATLAB's order."""
    return _read(raw, max_bytes, matlab=True)


def _read(raw: RawInput, max_bytes: int, matlab: bool) -> Source:
    kind = "a MATLAB v7.3 file" if matlab else "HDF5"
    shapes: dict[str, tuple[int, ...]] = {}
    units: dict[str, str] = {}
    keys: dict[str, str | bytes] = {}  # field name -> the dataset's path as h5py gives it

    def visit(key, item):
        # h5py gives a path that is not UTF-8 as bytes
        name = key.decode("utf-8", "replace") if isinstance(key, bytes) else key
        if not isinstance(item, _h5py().Dataset) or name.startswith("#") or "/#" in name:
            return
        if item.dtype.kind not in "fiub" or item.ndim not in (1, 2) or item.size == 0:
            return
        if matlab and _attribute_text(item.attrs.get("MATLAB_class")) == "char":
            return
        shape = item.shape[::-1] if matlab else item.shape
        shapes[name] = (max(shape),) if len(shape) == 2 and 1 in shape else shape
        keys[name] = key
        unit = _attribute_text(item.attrs.get("units", item.attrs.get("unit")))
        if unit:
            units[name] = unit

    with library_errors(kind, _H5PY_ERRORS):
        with _h5py().File(raw.file_or_buffer(), "r") as handle:
            handle.visititems(visit)

    def load(names, text_ok=()):
        arrays = {}
        budget = max_bytes
        with library_errors(kind, _H5PY_ERRORS), _h5py().File(raw.file_or_buffer(), "r") as handle:
            for name in names:
                dataset = handle[keys[name]]
                _check_dataset(dataset, name, raw.size, budget)
                budget -= dataset.size * 8
                array = np.asarray(dataset[()], dtype=float)
                array = array.T if matlab else array
                arrays[name] = array.reshape(shapes[name])
        return arrays

    if matlab:
        return Source(shapes, load, unit_attributes=units)

    def chunks(names, chunk_rows, sample_axes=None, text_ok=()) -> Iterator[Chunk]:
        sample_axes = sample_axes or {}
        check_allocation(
            f"{len(names)} fields of {chunk_rows} rows", 8 * chunk_rows * len(names), max_bytes
        )
        with library_errors(kind, _H5PY_ERRORS), _h5py().File(raw.file_or_buffer(), "r") as handle:
            datasets = {name: handle[keys[name]] for name in names}
            for name, dataset in datasets.items():
                _check_dataset(dataset, name, raw.size, max_bytes=None)
            rows = {_samples(dataset, sample_axes.get(name)) for name, dataset in datasets.items()}
            if len(rows) > 1:
                raise FileFormatError(f"the fields {list(names)} have different lengths")
            total = rows.pop() if rows else 0
            for start in range(0, total, chunk_rows):
                stop = min(start + chunk_rows, total)
                columns = {
                    name: _dataset_rows(dataset, sample_axes.get(name), start, stop)
                    for name, dataset in datasets.items()
                }
                yield Chunk(start, columns, sample_label)

    return Source(shapes, load, unit_attributes=units, chunks=chunks)


def _samples(dataset, sample_axis: int | None) -> int:
    """Samples in a dataset: its length, or that of the sample axis of a 2-D one."""
    if dataset.ndim == 1:
        return dataset.shape[0]
    if sample_axis is None:  # N x 1 or 1 x N: a vector
        return max(dataset.shape)
    return dataset.shape[sample_axis]


def _dataset_rows(dataset, sample_axis: int | None, start: int, stop: int) -> np.ndarray:
    """Samples ``start:stop`` of a dataset as float64, samples along the first axis."""
    if dataset.ndim == 1:
        values = dataset[start:stop]
    elif sample_axis is None:  # N x 1 or 1 x N: a vector
        values = dataset[start:stop, 0] if dataset.shape[1] == 1 else dataset[0, start:stop]
    elif sample_axis == 0:
        values = dataset[start:stop, :]
    else:
        values = dataset[:, start:stop].T
    return np.asarray(values, dtype=float)


def _h5py():
    import h5py

    return h5py


def _check_dataset(dataset, name: str, file_size: int, max_bytes: int | None) -> None:
    """Refuse a dataset stored outside the file, or larger than the limit (None: no limit,
    for a dataset read in slices) or the file."""
    h5py = _h5py()
    what = f"dataset {name!r}"
    if dataset.is_virtual:
        raise FileFormatError(
            f"{what} is a virtual dataset, whose values come from other files; only values "
            "stored in the file itself are read: copy them into it (h5repack or h5py)"
        )
    plist = dataset.id.get_create_plist()
    if plist.get_external_count() > 0:
        raise FileFormatError(
            f"{what} keeps its values in {plist.get_external_count()} external raw file(s); "
            "only values stored in the file itself are read: copy them into it (h5repack)"
        )
    if max_bytes is not None:
        check_allocation(f"{what} of shape {dataset.shape}", 8 * dataset.size, max_bytes)
    stored = dataset.size * dataset.dtype.itemsize
    if plist.get_layout() == h5py.h5d.CONTIGUOUS and plist.get_nfilters() == 0:
        offset = dataset.id.get_offset()
        if offset is not None and offset + stored > file_size:
            raise FileFormatError(
                f"{what} declares {stored} bytes of values at byte {offset}, but the file holds "
                f"only {file_size} bytes: it is truncated or damaged"
            )
    elif dataset.id.get_storage_size() > file_size:
        raise FileFormatError(
            f"{what} declares more stored bytes than the file holds: it is damaged"
        )


def _attribute_text(value) -> str | None:
    if value is None:
        return None
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray) and value.size == 1:
        return _attribute_text(value.item())
    return str(value)


def write_hdf5(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write 1-D columns as datasets at the root (text as UTF-8 strings); a ``/`` in a
    name makes groups."""
    h5py = _h5py()
    with h5py.File(path, "w") as handle:
        for name, values in arrays.items():
            try:
                if values.dtype.kind == "U":
                    text = values.astype(object)
                    handle.create_dataset(name, data=text, dtype=h5py.string_dtype())
                else:
                    handle.create_dataset(name, data=values)
            except (ValueError, KeyError, TypeError) as exc:
                raise InputError(
                    f"cannot write column {name!r} to HDF5 ({library_reason(exc)}): rename it, "
                    "or write another format"
                ) from exc


class HDF5ChunkWriter:
    """Writes 1-D columns to an HDF5 file one chunk at a time, as resizable datasets at
    the root (text as UTF-8 strings), like :func:`write_hdf5` once complete.

    Parameters
    ----------
    path : Path
        The file to write (a temporary file; the caller renames it).
    """

    def __init__(self, path: Path):
        self._handle = _h5py().File(path, "w")
        self._rows = 0
        self._created = False

    def write(self, arrays: dict[str, np.ndarray]) -> None:
        """Append rows: 1-D columns (float64, int64 or text) of one length, the same
        columns at every call."""
        h5py = _h5py()
        count = len(next(iter(arrays.values()))) if arrays else 0
        for name, values in arrays.items():
            text = values.dtype.kind == "U"
            data = values.astype(object) if text else values
            try:
                if not self._created:
                    self._handle.create_dataset(
                        name,
                        data=data,
                        maxshape=(None,),
                        chunks=(max(min(count, 1 << 16), 1),),
                        dtype=h5py.string_dtype() if text else values.dtype,
                    )
                    continue
                dataset = self._handle[name]
                dataset.resize((self._rows + count,))
                dataset[self._rows :] = data
            except (ValueError, KeyError, TypeError) as exc:
                raise InputError(
                    f"cannot write column {name!r} to HDF5 ({library_reason(exc)}): rename it, "
                    "or write another format"
                ) from exc
        self._created = True
        self._rows += count

    def close(self) -> None:
        """Finish the file."""
        self._handle.close()

    def abort(self) -> None:
        """Release the file after a failure (the caller removes it)."""
        self._handle.close()
