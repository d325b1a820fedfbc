"""What every format reader shares: the input read once, the size limit, named fields.

A reader gets a :class:`RawInput` (a regular file read in place, or a pipe, device or
standard input read once into memory, never more than the size limit) and returns a
:class:`Source`: the numeric fields of the file with their shapes, loaded on demand. Sizes
a file declares are checked against :data:`MAX_BYTES` (or the caller's limit) and against
the file's own size before anything is allocated.
"""

from __future__ import annotations

import contextlib
import io
import os
import stat
import struct
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np

from ..exceptions import FileFormatError, InputError, WavemeterError

__all__ = [
    "MAX_BYTES",
    "STDIN",
    "RawInput",
    "Source",
    "Chunk",
    "whole_chunks",
    "open_input",
    "check_allocation",
    "array_source",
    "flatten",
    "library_errors",
    "library_reason",
    "sample_label",
]

#: the most bytes a reader allocates for the values it reads from one file (2 GiB), and the
#: most it reads from a pipe or device; ``read_table(..., max_bytes=)`` overrides it
MAX_BYTES = 2**31
#: the input path that means standard input
STDIN = "-"
_CHUNK_BYTES = 1 << 20


@dataclass(frozen=True)
class RawInput:
    """A data file as given: a regular file read in place, or any other input read once.

    Attributes
    ----------
    path : Path
        The name the user gave (``-`` for standard input), used in messages.
    size : int
        Size in bytes (of the file, or of what was read from a pipe or device).
    content : bytes or None
        The whole content of an input that is not a regular file, read once; None for a
        regular file, which is read in place.
    """

    path: Path
    size: int
    content: bytes | None = None

    @property
    def suffix(self) -> str:
        """The file extension in lower case (``".csv"``), ``""`` when none."""
        return self.path.suffix.lower()

    def open(self) -> BinaryIO:
        """A fresh binary file object positioned at the start."""
        if self.content is not None:
            return io.BytesIO(self.content)
        return open(self.path, "rb")

    def file_or_buffer(self) -> str | BinaryIO:
        """The path as text for a regular file (libraries read it faster), else a buffer."""
        return str(self.path) if self.content is None else io.BytesIO(self.content)

    def head(self, count: int) -> bytes:
        """The first ``count`` bytes (fewer when the input is shorter)."""
        if self.content is not None:
            return self.content[:count]
        with open(self.path, "rb") as handle:
            return handle.read(count)

    def tail(self, count: int) -> bytes:
        """The last ``count`` bytes (all of them when the input is shorter)."""
        if self.content is not None:
            return self.content[-count:]
        with open(self.path, "rb") as handle:
            handle.seek(max(self.size - count, 0))
            return handle.read(count)


def open_input(path, max_bytes: int, refuse_chunk: Callable[[bytes, bytes], str | None]):
    """The input at ``path``: a regular file as it is, anything else read once into memory.

    Parameters
    ----------
    path : str or Path
        The file; ``"-"`` reads standard input.
    max_bytes : int
        The most bytes read from an input that is not a regular file.
    refuse_chunk : callable
        ``refuse_chunk(head, chunk)`` is called for each chunk read from a stream (``head``
        is its first bytes); a text returned stops reading with that reason (a stream of
        NUL bytes is no table, and need not be read to its end to know it).

    Raises
    ------
    InputError
        When the file does not exist or is a folder.
    FileFormatError
        When a stream is longer than ``max_bytes`` or ``refuse_chunk`` refuses it.
    """
    name = Path(path)
    if str(path) == STDIN:
        return _spool(sys.stdin.buffer, name, max_bytes, refuse_chunk)
    try:
        mode = os.stat(name).st_mode
    except FileNotFoundError:
        raise InputError("file not found") from None
    if stat.S_ISDIR(mode):
        raise InputError("is a folder, not a data file")
    if stat.S_ISREG(mode):
        return RawInput(name, os.stat(name).st_size)
    with open(name, "rb", buffering=0) as stream:
        return _spool(stream, name, max_bytes, refuse_chunk)


def _spool(stream, name: Path, max_bytes: int, refuse_chunk) -> RawInput:
    """Read a pipe, device or standard input once, at most ``max_bytes`` bytes."""
    chunks: list[bytes] = []
    total = 0
    head = b""
    while True:
        chunk = stream.read(min(_CHUNK_BYTES, max_bytes + 1 - total))
        if not chunk:
            break
        if len(head) < 1024:
            head = (head + chunk)[:1024]
        reason = refuse_chunk(head, chunk)
        if reason:
            raise FileFormatError(reason)
        chunks.append(chunk)
        total += len(chunk)
        if total > max_bytes:
            raise FileFormatError(
                f"is not a regular file (a pipe or device) and holds more than {max_bytes} "
                "bytes, the size limit: save the data to a file, or raise the limit (max_bytes)",
                parameter="max_bytes",
            )
    content = b"".join(chunks)
    return RawInput(name, len(content), content)


def check_allocation(what: str, needed_bytes: int, max_bytes: int) -> None:
    """Refuse to read what a file declares when it would take more than the limit.

    Called before anything is read or allocated.

    Parameters
    ----------
    what : str
        The field as the user sees it (``"dataset 'scan/P' of shape (4, 1000000000)"``).
    needed_bytes : int
        Bytes it would take once read (8 per float64 value).
    max_bytes : int
        The limit.
    """
    if needed_bytes > max_bytes:
        raise FileFormatError(
            f"{what} would take {_size_text(needed_bytes)}, more than the "
            f"{_size_text(max_bytes)} size limit: the file is damaged or not a table of "
            "readings; if the size is right, raise the limit (max_bytes)",
            parameter="max_bytes",
        )


def _size_text(count: int) -> str:
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= size:
            return f"{count / size:.3g} {unit}"
    return f"{count} bytes"


@contextlib.contextmanager
def library_errors(kind: str, errors: tuple[type[BaseException], ...]):
    """Turn what a file library raises on a damaged file into one FileFormatError.

    Parameters
    ----------
    kind : str
        The format as the user knows it (``"HDF5"``, ``"NPZ"``), for the message.
    errors : tuple of exception classes
        What the library raises on a damaged or foreign file; anything else propagates
        (the package's own errors unchanged, anything unforeseen as a bug).
    """
    try:
        yield
    except WavemeterError:
        raise
    except errors as exc:
        raise FileFormatError(
            f"cannot read it as {kind} ({library_reason(exc)}): the file is damaged or not "
            "of this format"
        ) from exc


#: exceptions whose text describes Python's own objects, not the file: never shown
_PYTHON_INTERNAL_ERRORS = (TypeError, AttributeError, IndexError, UnicodeError, struct.error)


def library_reason(exc: BaseException) -> str:
    """The text of an exception a file library raised, without Python's decoration, or
    ``"unreadable content"`` when its text would only describe Python internals."""
    if isinstance(exc, _PYTHON_INTERNAL_ERRORS):
        return "unreadable content"
    if exc.args and isinstance(exc.args[0], str) and exc.args[0].strip():
        return " ".join(exc.args[0].split())
    return "unreadable content"


# ---------------------------------------------------------------------------- named fields
def sample_label(index: int) -> str:
    """The label of zero-based sample ``index`` in a file without lines: ``row 1``, ..."""
    return f"row {index + 1}"


@dataclass
class Source:
    """Named numeric arrays of one file: shapes up front, values loaded on demand.

    Attributes
    ----------
    shapes : dict of str to tuple of int
        Each field's shape in the user's orientation (MATLAB v7.3 arrays already
        transposed back; an N x 1 or 1 x N matrix as a vector); ``(-1,)`` for a column of
        a text file, whose length is known once read.
    load : callable
        ``load(names, text_ok)`` returns those fields as float64 arrays; a field named in
        ``text_ok`` may come back as text.
    row_label : callable
        ``row_label(i)`` names zero-based data row ``i`` as the user finds it in the file
        (``line 7`` in a text file, ``row 5`` elsewhere).
    unit_attributes : dict of str to str
        Units stored beside the data (HDF5 ``units`` attributes).
    chunks : callable or None
        ``chunks(names, chunk_rows, sample_axes, text_ok)`` yields :class:`Chunk` s of at
        most ``chunk_rows`` rows, in file order, reading the file once and holding only
        one chunk at a time; ``sample_axes[name]`` is the axis of a 2-D field that runs
        over the samples. None: the format reads whole fields only
        (:func:`whole_chunks` slices them).
    count_rows : callable or None
        ``count_rows()`` counts the data rows of a file whose fields do not declare their
        length (a text file) by a fast pass over it, for progress; None: the fields
        declare it.
    decimal : str
        The decimal mark of the file's text cells (``","`` in a text file read with
        decimal commas), for turning a text field into numbers.
    note : str or None
        What the reader chose that the caller did not say (a text file read with decimal
        commas), for an :class:`~wavemeter.exceptions.InputNote`.
    """

    shapes: dict[str, tuple[int, ...]]
    load: Callable[..., dict[str, np.ndarray]]
    row_label: Callable[[int], str] = sample_label
    unit_attributes: dict[str, str] = field(default_factory=dict)
    chunks: Callable[..., Iterator[Chunk]] | None = None
    count_rows: Callable[[], int] | None = None
    decimal: str = "."
    note: str | None = None


@dataclass(frozen=True)
class Chunk:
    """Consecutive data rows of a file, read by :attr:`Source.chunks`.

    Attributes
    ----------
    start : int
        Zero-based index of the first row among the file's data rows.
    columns : dict of str to ndarray, shape (m,) or (m, k)
        The fields asked for, samples along the first axis (a 2-D field already turned
        so), float64 or, for a field allowed to be text, str.
    row_label : callable
        ``row_label(i)`` names data row ``i`` (zero-based, file-wide, ``start <= i <
        start + m``) as the user finds it (``line 7``, ``row 5``).
    """

    start: int
    columns: dict[str, np.ndarray]
    row_label: Callable[[int], str]

    @property
    def n_rows(self) -> int:
        """Rows m in this chunk."""
        return len(next(iter(self.columns.values())))


def whole_chunks(
    source: Source, names, chunk_rows: int, sample_axes: dict[str, int], text_ok=()
) -> Iterator[Chunk]:
    """Chunks of a source read whole (formats that cannot read part of a field: MAT, and
    fields stored in an order that cannot be read row by row): the memory is that of the
    whole fields, the rows come out in chunks all the same.

    Parameters
    ----------
    source : Source
        The file.
    names : list of str
        Fields to read.
    chunk_rows : int
        Rows per chunk.
    sample_axes : dict of str to int
        For each 2-D field, the axis that runs over the samples.
    text_ok : collection of str
        Fields that may come back as text.
    """
    data = source.load(list(names), text_ok=set(text_ok))
    for name, axis in sample_axes.items():
        if axis == 1:
            data[name] = data[name].T
    rows = len(next(iter(data.values()))) if data else 0
    for start in range(0, rows, chunk_rows):
        stop = min(start + chunk_rows, rows)
        yield Chunk(
            start, {name: values[start:stop] for name, values in data.items()}, source.row_label
        )


def array_source(arrays: dict[str, object], max_bytes: int) -> Source:
    """A source over arrays in memory: the numeric 1-D and 2-D ones (N x 1, 1 x N as 1-D)."""
    fields = {}
    for name, value in arrays.items():
        if not isinstance(value, np.ndarray):
            continue  # scalars, text, cell arrays and structure arrays hold no columns
        if value.dtype.kind in "fiub" and value.ndim in (1, 2) and value.size:
            fields[name] = value.reshape(-1) if value.ndim == 2 and 1 in value.shape else value

    def load(names, text_ok=()):
        check_allocation("the fields read", 8 * sum(fields[name].size for name in names), max_bytes)
        return {name: np.asarray(fields[name], dtype=float) for name in names}

    return Source(shapes={name: array.shape for name, array in fields.items()}, load=load)


def flatten(tree: dict, prefix: str = "") -> dict[str, object]:
    """Nested dictionaries (MATLAB structures) as one level: ``{"sweep/P_dBm": array}``.

    Keys starting ``__`` (MATLAB file headers) are left out.
    """
    flat: dict[str, object] = {}
    for key, value in tree.items():
        key = key.decode("latin-1") if isinstance(key, bytes) else str(key)
        if key.startswith("__"):
            continue
        if isinstance(value, dict):
            flat.update(flatten(value, f"{prefix}{key}/"))
        else:
            flat[f"{prefix}{key}"] = value
    return flat
