"""The in-memory table of readings one file gives: SI values, roles, invalid rows."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Table", "InvalidRows"]


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
    invalid_code : ndarray of int, shape (N,)
        -1 for a valid row, else the index in ``invalid_reasons`` of its first problem
        (NaN/inf, power-meter sentinel, implausible dBm, no light, bad monitor reading).
    row_index : ndarray of int, shape (N,)
        Zero-based index of each row among the file's data rows.
    rows_in_file : int
        Number of data rows in the file.
    row_label : callable
        ``row_label(i)`` names data row ``i`` (zero-based, as in ``row_index``) the way
        the user finds it in the file: ``line 7`` (file line, header and comments counted)
        in a text file, ``row 5`` in an array file.
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
    invalid_reasons : tuple of str
        Text of each problem found.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> folder = Path(tempfile.mkdtemp())
    >>> columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    >>> write_table(folder / "sweep.csv", columns)  # the sweep as a lab would save it
    >>> from wavemeter.io import read_table
    >>> table = read_table(folder / "sweep.csv")
    >>> table.powers_w.shape, table.port_names, table.x_column
    ((200, 3), ('p1_w', 'p2_w', 'p3_w'), 'frequency_hz')
    >>> print(np.array_equal(table.x_hz, f_hz), np.array_equal(table.powers_w, powers))  # exact
    True True
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


class InvalidRows:
    """Collects per-row problems while a table is read: a mask and each row's first reason.

    Parameters
    ----------
    rows : int
        Number of data rows N.
    """

    def __init__(self, rows: int):
        self.mask = np.zeros(rows, dtype=bool)
        self.code = np.full(rows, -1)
        self.reasons: list[str] = []

    def add(self, mask: np.ndarray, reason: str) -> None:
        """Flag the rows of boolean ``mask`` (N,) with ``reason``, unless already flagged."""
        fresh = mask & ~self.mask
        if fresh.any():
            self.code[fresh] = len(self.reasons)
            self.reasons.append(reason)
            self.mask |= mask
