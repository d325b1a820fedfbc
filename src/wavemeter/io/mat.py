"""MATLAB ``.mat`` files: v5 by the package's own element parser, v4 through scipy.io,
v7.3 as HDF5. Read only.

A v5 file is a sequence of (maybe zlib-compressed) ``miMATRIX`` elements. Real numeric
arrays are fields; 1 x 1 structures are opened for their numeric fields, named by path
(``sweep/wavelength_nm``); text, cells, sparse and complex arrays, objects and structure
arrays are left out. Every element's declared size is checked against the bytes that hold
it, and a variable against the size limit, before anything is decompressed or converted,
so a damaged file gives a :class:`~wavemeter.exceptions.FileFormatError`, never a crash
or an allocation it does not justify. scipy is imported only for v4 files.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ..exceptions import FileFormatError
from .hdf5 import read_mat73
from .source import RawInput, Source, array_source, check_allocation, flatten, library_errors

__all__ = ["read_mat"]

_MI_MATRIX, _MI_COMPRESSED = 14, 15
_MI_INT32, _MI_UINT32 = 5, 6
_STRUCT = 2
_NUMERIC_CLASSES = range(6, 16)  # double, single, int8 ... uint64 (logical is uint8)
_COMPLEX_FLAG = 0x800
_HEADER_BYTES = 128
_MAX_DEPTH = 32
#: MAT data type -> numpy type code of the stored numbers
_STORED_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 9: "f8"}
_STORED_TYPES |= {12: "i8", 13: "u8"}


@dataclass(frozen=True)
class _Array:
    """The header of a MATLAB array element and where its contents start."""

    name: str
    matlab_class: int
    complex: bool
    dims: tuple[int, ...]
    body: bytes  # the element's data (after its tag)
    contents: int  # offset in ``body`` after flags, dims and name

    @property
    def is_real_matrix(self) -> bool:
        return (
            self.matlab_class in _NUMERIC_CLASSES
            and not self.complex
            and len(self.dims) == 2
            and math.prod(self.dims) > 1  # a 1 x 1 scalar is a setting, not a column
        )


@dataclass(frozen=True)
class _Variable:
    """A top-level variable: its header and where its element lies in the file."""

    array: _Array
    position: int
    byte_count: int
    compressed: bool


def read_mat(raw: RawInput, max_bytes: int) -> Source:
    """The numeric arrays of a MATLAB file, structures flattened (``sweep/P_dBm``)."""
    head = raw.head(1024)
    if head[512:516] == b"\x89HDF":
        return read_mat73(raw, max_bytes)
    if head[126:128] not in (b"IM", b"MI"):
        return _read_v4(raw, max_bytes)
    order = "<" if head[126:128] == b"IM" else ">"
    shapes: dict[str, tuple[int, ...]] = {}
    loaders: dict[str, Callable[[], np.ndarray]] = {}
    for variable in _scan(raw, order):
        array = variable.array
        if array.name.startswith("__"):
            continue
        if array.is_real_matrix:
            shapes[array.name] = _field_shape(array.dims)
            loaders[array.name] = _top_level_loader(raw, variable, order, max_bytes)
        elif array.matlab_class == _STRUCT:
            check_allocation(f"structure {array.name!r}", variable.byte_count, max_bytes)
            whole = _array_header(_element_data(raw, variable, order, max_bytes), order, array.name)
            for path, values in _structure_fields(whole, order, array.name, depth=0):
                shapes[path] = _field_shape(values.shape)
                loaders[path] = lambda values=values: values

    def load(names, text_ok=()):
        cells = sum(math.prod(shapes[name]) for name in names)
        check_allocation(f"the variables {names}", 8 * cells, max_bytes)
        return {
            name: np.asarray(loaders[name](), dtype=float).reshape(shapes[name]) for name in names
        }

    return Source(shapes, load)


def _field_shape(dims: tuple[int, ...]) -> tuple[int, ...]:
    """MATLAB's N x 1 and 1 x N vectors as 1-D fields; other matrices as they are."""
    return (max(dims),) if 1 in dims else tuple(dims)


def _read_v4(raw: RawInput, max_bytes: int) -> Source:
    """A MATLAB v4 file (or a foreign one): uncompressed, so its values fit in its size."""
    check_allocation("the file", raw.size, max_bytes)
    from scipy import io as scipy_io
    from scipy.io.matlab import MatReadError, matfile_version

    errors = (MatReadError, ValueError, TypeError, IndexError, KeyError, OverflowError)
    errors += (EOFError, OSError, UnicodeDecodeError, zlib.error)
    with library_errors("a MATLAB file", errors):
        if matfile_version(raw.file_or_buffer())[0] != 0:
            raise FileFormatError(
                "cannot read it as a MATLAB file: its v5 header is damaged (no byte-order mark)"
            )
        contents = scipy_io.loadmat(raw.file_or_buffer(), simplify_cells=True)
    return array_source(flatten(contents), max_bytes)


# ---------------------------------------------------------------------------- elements
def _scan(raw: RawInput, order: str) -> Iterator[_Variable]:
    """The top-level variables of a v5 file, each element's size checked against the file."""
    position = _HEADER_BYTES
    with raw.open() as handle:
        while position + 8 <= raw.size:
            handle.seek(position)
            tag = handle.read(8)
            data_type, byte_count = struct.unpack(order + "II", tag)
            where = f"variable at byte {position}"
            if data_type == 0 and byte_count == 0:
                break  # zero padding at the end of the file
            if position + 8 + byte_count > raw.size:
                raise FileFormatError(
                    f"{where} declares {byte_count} bytes, past the end of the {raw.size}-byte "
                    "file: it is truncated or damaged"
                )
            start = handle.read(min(byte_count, 1 << 16))
            if data_type == _MI_COMPRESSED:
                element = _inflate(start, 1 << 16, where)
                if len(element) < 8:
                    raise FileFormatError(f"{where} is compressed but holds no array: damaged")
                inner_type, inner_count = struct.unpack(order + "II", element[:8])
                body = element[8:]
            elif data_type == _MI_MATRIX:
                inner_type, inner_count, body = data_type, byte_count, start
            else:
                raise FileFormatError(f"{where} is of element type {data_type}: it is damaged")
            if inner_type != _MI_MATRIX:
                raise FileFormatError(f"{where} is not a MATLAB array: it is damaged")
            array = _array_header(body, order, where)
            yield _Variable(array, position, inner_count, data_type == _MI_COMPRESSED)
            position += 8 + byte_count


def _inflate(compressed: bytes, limit: int, where: str) -> bytes:
    """At most ``limit`` bytes of a zlib stream, without inflating the rest."""
    try:
        return zlib.decompressobj().decompress(compressed, limit)
    except zlib.error as exc:
        raise FileFormatError(f"{where} is compressed but damaged ({exc})") from None


def _element_data(raw: RawInput, variable: _Variable, order: str, max_bytes: int) -> bytes:
    """The whole data of a top-level miMATRIX element (decompressed), tag excluded."""
    where = f"variable {variable.array.name!r}"
    check_allocation(where, variable.byte_count, max_bytes)
    with raw.open() as handle:
        handle.seek(variable.position)
        _, stored = struct.unpack(order + "II", handle.read(8))
        payload = handle.read(stored)
    if not variable.compressed:
        return payload
    element = _inflate(payload, variable.byte_count + 8, where)
    if len(element) != variable.byte_count + 8:
        raise FileFormatError(f"{where} decompresses to another size than declared: damaged")
    return element[8:]


def _element(data: bytes, offset: int, order: str, where: str) -> tuple[int, bytes, int]:
    """``(data type, data, next offset)`` of the sub-element at ``offset`` (both formats)."""
    if offset + 8 > len(data):
        raise FileFormatError(f"{where} ends inside an element header: it is damaged")
    first, second = struct.unpack(order + "II", data[offset : offset + 8])
    if first >> 16:  # small data element: type and size in one word, data in the next
        size = first >> 16
        if size > 4:
            raise FileFormatError(f"{where} has a malformed small element: it is damaged")
        return first & 0xFFFF, data[offset + 4 : offset + 4 + size], offset + 8
    end = offset + 8 + second
    if end > len(data):
        raise FileFormatError(f"{where} declares an element longer than its data: it is damaged")
    return first, data[offset + 8 : end], end + (-second % 8)


def _array_header(body: bytes, order: str, where: str) -> _Array:
    """Flags, dims and name at the start of a miMATRIX element's data."""
    kind, flags, offset = _element(body, 0, order, where)
    kind_dims, dims_bytes, offset = _element(body, offset, order, where)
    _, name, offset = _element(body, offset, order, where)
    if kind != _MI_UINT32 or len(flags) < 4 or kind_dims != _MI_INT32 or len(dims_bytes) % 4:
        raise FileFormatError(f"{where} has a malformed array header: it is damaged")
    (flag_word,) = struct.unpack(order + "I", flags[:4])
    dims = struct.unpack(f"{order}{len(dims_bytes) // 4}i", dims_bytes)
    if any(size < 0 for size in dims):
        raise FileFormatError(f"{where} declares negative dimensions {dims}: it is damaged")
    return _Array(
        name=name.decode("latin-1").rstrip("\x00"),
        matlab_class=flag_word & 0xFF,
        complex=bool(flag_word & _COMPLEX_FLAG),
        dims=tuple(dims),
        body=body,
        contents=offset,
    )


def _real_values(array: _Array, order: str, where: str) -> np.ndarray:
    """The real part of a numeric array in MATLAB's (column-major) order, shape ``dims``."""
    kind, data, _ = _element(array.body, array.contents, order, where)
    if kind not in _STORED_TYPES:
        raise FileFormatError(f"{where} stores its values as data type {kind}: it is damaged")
    dtype = np.dtype(_STORED_TYPES[kind]).newbyteorder(order)
    count = math.prod(array.dims)
    if len(data) != count * dtype.itemsize:
        raise FileFormatError(
            f"{where} declares {count} values but holds {len(data)} bytes of "
            f"{dtype.name}: it is damaged"
        )
    return np.frombuffer(data, dtype=dtype).reshape(array.dims, order="F")


def _top_level_loader(raw: RawInput, variable: _Variable, order: str, max_bytes: int):
    def load() -> np.ndarray:
        where = f"variable {variable.array.name!r}"
        whole = _array_header(_element_data(raw, variable, order, max_bytes), order, where)
        return _real_values(whole, order, where)

    return load


def _structure_fields(
    array: _Array, order: str, path: str, depth: int
) -> Iterator[tuple[str, np.ndarray]]:
    """``(path, values)`` of the real numeric arrays in a 1 x 1 structure, recursively."""
    where = f"structure {path!r}"
    if depth > _MAX_DEPTH:
        raise FileFormatError(f"{where} nests structures more than {_MAX_DEPTH} deep")
    if math.prod(array.dims) != 1:
        return  # a structure array: no columns
    _, width_bytes, offset = _element(array.body, array.contents, order, where)
    _, names, offset = _element(array.body, offset, order, where)
    width = struct.unpack(order + "i", width_bytes[:4])[0] if len(width_bytes) >= 4 else 0
    if width <= 0 or len(names) % width:
        raise FileFormatError(f"{where} has malformed field names: it is damaged")
    for start in range(0, len(names), width):
        field = names[start : start + width].split(b"\x00", 1)[0].decode("latin-1")
        kind, data, offset = _element(array.body, offset, order, where)
        if kind != _MI_MATRIX or not data:
            continue  # an empty field
        inner = _array_header(data, order, f"{path}/{field}")
        if inner.is_real_matrix:
            yield f"{path}/{field}", _real_values(inner, order, f"field {path}/{field}")
        elif inner.matlab_class == _STRUCT:
            yield from _structure_fields(inner, order, f"{path}/{field}", depth + 1)
