"""Logging every published reading to per-channel Parquet files, and reading a log back.

A :class:`ParquetLog` runs a writer thread. Readings wait in memory at most ``flush_s``
(default 0.5 s): then each channel's are written as a small Parquet file of their own, a
*part* (``ch0/<segment>.part000001.parquet``, written beside and renamed, so every file in
the folder is always whole). When a segment is older than ``rotate_s`` or its parts larger
than ``rotate_bytes``, and when the log closes, its parts are joined into one file
``ch0/<segment>.parquet`` (renamed into place before the parts go). So after SIGTERM every
reading is in a segment file, and after ``kill -9`` every file is readable and only the
readings of the last flush interval are missing; a new run starts new segments, and joins
the parts a killed run left. :func:`read_log` reads a folder back as one table.

Columns are the published fields (``channel`` first), with the port powers (``P1_w``, ...)
when asked; a change of fields (a reload) starts a new segment.
"""

from __future__ import annotations

import os
import queue
import re
import threading
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..exceptions import InputError

__all__ = ["ParquetLog", "read_log", "FLUSH_S", "ROTATE_S", "ROTATE_BYTES"]

FLUSH_S = 0.5
ROTATE_S = 3600.0
ROTATE_BYTES = 256 * 2**20
_PART = re.compile(r"^(?P<segment>.+)\.part(?P<part>\d{6})\.parquet$")


class _Segment:
    """One channel's open segment: its name, fields, parts and bytes so far."""

    def __init__(self, folder: Path, name: str, fields: tuple[str, ...]):
        self.folder = folder
        self.name = name
        self.fields = fields
        self.started = time.monotonic()
        self.parts: list[Path] = []
        self.bytes = 0

    def write_part(self, table: pa.Table) -> None:
        path = self.folder / f"{self.name}.part{len(self.parts) + 1:06d}.parquet"
        _write(table, path)
        self.parts.append(path)
        self.bytes += path.stat().st_size

    def close(self) -> None:
        if self.parts:
            _join(self.parts, self.folder / f"{self.name}.parquet")


class ParquetLog:
    """Per-channel Parquet logs of a service, written by a thread.

    Parameters
    ----------
    folder : str or Path
        The log folder (made if missing); each channel writes into ``ch<index>/``.
    run : str
        The service run, in the segment names.
    flush_s : float
        Most seconds a reading waits in memory (<= 1).
    rotate_s, rotate_bytes : float, int
        Age and size at which a segment is closed and a new one begun.
    """

    def __init__(
        self, folder, run: str, *, flush_s=FLUSH_S, rotate_s=ROTATE_S, rotate_bytes=ROTATE_BYTES
    ):
        self.folder = Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"{folder}: cannot make the log folder ({exc.strerror})") from None
        if not os.access(self.folder, os.W_OK):
            raise InputError(f"{folder}: the log folder is not writable")
        self.run = run
        self.flush_s = flush_s
        self.rotate_s = rotate_s
        self.rotate_bytes = rotate_bytes
        self.rows = 0
        self.error: str | None = None
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._segments: dict[int, _Segment] = {}
        self._pending: dict[int, list[dict]] = {}
        recover(self.folder)
        self._thread = threading.Thread(target=self._work, name="wavemeter-log", daemon=True)
        self._thread.start()

    def append(self, channel: int, columns: dict[str, np.ndarray]) -> None:
        """Queue a batch's columns to be logged (any thread)."""
        self._queue.put((channel, columns))

    def close(self) -> None:
        """Write everything queued, join every segment's parts, stop the thread."""
        self._queue.put(None)
        self._thread.join()

    def _work(self) -> None:
        deadline = time.monotonic() + self.flush_s
        while True:
            try:
                item = self._queue.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                item = ()
            if item is None:
                break
            if item:
                channel, columns = item
                self._pending.setdefault(channel, []).append(columns)
            if time.monotonic() >= deadline:
                self._flush()
                deadline = time.monotonic() + self.flush_s
        self._flush()
        for segment in self._segments.values():
            self._guard(segment.close)

    def _flush(self) -> None:
        pending, self._pending = self._pending, {}
        for channel, batches in pending.items():
            self._guard(lambda c=channel, b=batches: self._write(c, b))
        for channel, segment in list(self._segments.items()):
            old = time.monotonic() - segment.started >= self.rotate_s
            if old or segment.bytes >= self.rotate_bytes:
                self._guard(segment.close)
                del self._segments[channel]

    def _write(self, channel: int, batches: list[dict]) -> None:
        fields = tuple(batches[0])
        groups: list[list[dict]] = [[]]
        for columns in batches:  # a change of fields starts a new segment
            if tuple(columns) != fields:
                groups.append([])
                fields = tuple(columns)
            groups[-1].append(columns)
        for group in groups:
            if not group:
                continue
            names = tuple(group[0])
            segment = self._segments.get(channel)
            if segment is None or segment.fields != names:
                if segment is not None:
                    segment.close()
                segment = self._segments[channel] = self._open(channel, names)
            rows = sum(len(c[names[0]]) for c in group)
            data = {"channel": np.full(rows, channel, dtype=np.int64)}
            data.update({name: np.concatenate([c[name] for c in group]) for name in names})
            segment.write_part(pa.table(data))
            self.rows += rows

    def _open(self, channel: int, fields: tuple[str, ...]) -> _Segment:
        folder = self.folder / f"ch{channel}"
        folder.mkdir(exist_ok=True)
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        name = f"{stamp}-{self.run}"
        taken = {p.name.split(".")[0] for p in folder.glob(f"{name}*.parquet")}
        suffix = 1
        while (f"{name}-{suffix}" if suffix > 1 else name) in taken:
            suffix += 1
        return _Segment(folder, f"{name}-{suffix}" if suffix > 1 else name, fields)

    def _guard(self, action) -> None:
        """Run a write; an OSError is kept (status shows it) and logging goes on."""
        try:
            action()
        except OSError as exc:
            self.error = f"{exc.filename or self.folder}: {exc.strerror or exc}"


def _write(table: pa.Table, path: Path) -> None:
    temporary = path.with_name(f".{path.name}.tmp")
    pq.write_table(table, temporary)
    os.replace(temporary, path)


def _join(parts: list[Path], path: Path) -> None:
    """Join parts into one file (renamed into place), then remove the parts."""
    tables = [pq.read_table(part) for part in parts]
    _write(pa.concat_tables(tables, promote_options="default"), path)
    for part in parts:
        part.unlink(missing_ok=True)


def recover(folder: Path) -> None:
    """Join the parts a killed run left into their segment files (or drop parts that a
    segment file already holds)."""
    for channel in folder.glob("ch*"):
        segments: dict[str, list[Path]] = {}
        for path in sorted(channel.glob("*.part*.parquet")):
            match = _PART.match(path.name)
            if match:
                segments.setdefault(match["segment"], []).append(path)
        for segment, parts in segments.items():
            joined = channel / f"{segment}.parquet"
            if joined.exists():
                for part in parts:
                    part.unlink(missing_ok=True)
            else:
                _join(parts, joined)


def log_files(folder) -> list[Path]:
    """The log's files in order: by channel, then segment, then part; parts a segment file
    already holds are left out."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: no such log folder")
    found = []
    for channel in sorted(folder.glob("ch*"), key=lambda p: (len(p.name), p.name)):
        names = {p.name for p in channel.glob("*.parquet")}
        for path in sorted(channel.glob("*.parquet")):
            match = _PART.match(path.name)
            if match and f"{match['segment']}.parquet" in names:
                continue
            found.append(path)
    return found


def read_log(folder, *, channel: int | None = None) -> pa.Table:
    """A service's log folder as one table.

    Parameters
    ----------
    folder : str or Path
        The ``--log`` folder.
    channel : int, optional
        Only this channel.

    Returns
    -------
    pyarrow.Table
        One row per logged reading, by channel then time; the published fields as columns
        (``channel``, ``sequence``, ``source_time_ns``, ``time_ns``, ``frequency_hz``, ...),
        a field some files lack is null there. ``.to_pandas()`` gives a DataFrame.

    Raises
    ------
    InputError
        When the folder does not exist or holds no log file.
    """
    files = log_files(folder)
    if channel is not None:
        files = [path for path in files if path.parent.name == f"ch{channel}"]
    if not files:
        raise InputError(
            f"{folder}: no log files" + ("" if channel is None else f" of ch{channel}")
        )
    tables = [pq.read_table(path) for path in files]
    return pa.concat_tables(tables, promote_options="default")
