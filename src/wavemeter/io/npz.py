"""NumPy ``.npz`` archives: reading and writing.

Only the ``.npy`` headers are read to list the fields; a member's values are decompressed
only when that field is used, after its declared size has been checked against the size
limit and against the member's size in the archive (an unused 3 GB member of a 3 MB archive
is never expanded). Object arrays (pickles) are refused. Written member names are made safe
for any unzip tool: no folders, no leading dot, no control characters.
"""

from __future__ import annotations

import math
import re
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np

from ..exceptions import FileFormatError, InputError
from .source import RawInput, Source, check_allocation, library_errors

__all__ = ["read_npz", "write_npz", "member_name"]

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
        shape, _, dtype = header
        return tuple(shape), dtype, member.tell()


def read_npz(raw: RawInput, max_bytes: int) -> Source:
    """The numeric 1-D and 2-D arrays of an NPZ archive, decompressed only when used."""
    members: dict[str, zipfile.ZipInfo] = {}
    shapes: dict[str, tuple[int, ...]] = {}
    with library_errors("NPZ", _ARCHIVE_ERRORS), zipfile.ZipFile(raw.open()) as archive:
        for info in archive.infolist():
            if not info.filename.endswith(".npy") or info.is_dir():
                continue
            name = info.filename[: -len(".npy")]
            shape, dtype, header_bytes = _read_header(archive, info)
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

    return Source(shapes, load)


_UNSAFE = re.compile(r"[\x00-\x1f\x7f/\\:]")


def member_name(column: str) -> str:
    """A safe archive member name for a column (without ``.npy``): folder separators,
    drive colons and control characters become ``_``, a leading dot gets a ``_`` before it
    (``../../x`` -> ``_.._.._x``)."""
    safe = _UNSAFE.sub("_", column)
    return "_" + safe if not safe or safe.startswith(".") else safe


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write 1-D columns as an uncompressed NPZ (like ``numpy.savez``), one member each."""
    names = {column: member_name(column) for column in arrays}
    seen: dict[str, str] = {}
    for column, safe in names.items():
        if safe in seen:
            raise InputError(
                f"columns {seen[safe]!r} and {column!r} both become NPZ member {safe!r} "
                "(folder separators and control characters are replaced): rename one"
            )
        seen[safe] = column
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as archive:
        for column, values in arrays.items():
            with archive.open(f"{names[column]}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, values, allow_pickle=False)
