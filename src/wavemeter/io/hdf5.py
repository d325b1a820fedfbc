"""HDF5 files (and MATLAB v7.3 files, which are HDF5): reading and writing.

Numeric 1-D and 2-D datasets anywhere in the group tree are fields named by their path
(``scan/frequency``); a ``units`` (or ``unit``) attribute gives their unit. Only objects
reached through hard links are read: soft and external links are not followed, and
datasets whose values live outside the file (external raw storage, virtual datasets) are
refused. A dataset's declared size is checked against the size limit and, for contiguous
uncompressed storage, against the file's size before it is read; any error of the HDF5
library on a damaged file becomes a :class:`~wavemeter.exceptions.FileFormatError`.
h5py is imported when a file is read or written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import FileFormatError, InputError
from .source import RawInput, Source, check_allocation, library_errors, library_reason

__all__ = ["read_hdf5", "read_mat73", "write_hdf5"]

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

    return Source(shapes, load, unit_attributes=units)


def _h5py():
    import h5py

    return h5py


def _check_dataset(dataset, name: str, file_size: int, max_bytes: int) -> None:
    """Refuse a dataset stored outside the file, or larger than the limit or the file."""
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
