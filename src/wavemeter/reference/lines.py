"""A table of reference absorption lines: centres, their uncertainties, pressure shifts.

:class:`ReferenceLines` holds the lines of a gas cell (a label, the centre frequency and its
standard uncertainty, optionally the pressure shift per pascal) and where the numbers came
from. :meth:`ReferenceLines.read_csv` reads the table users supply; no table of a standard
cell ships with the package (none could be checked against its published source here).
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..exceptions import FileFormatError, InputError, shown
from ..units import FREQUENCY_UNITS, OPTICAL_BAND_HZ, SPEED_OF_LIGHT_M_S

__all__ = ["ReferenceLines", "LINE_TABLE_COLUMNS", "MAX_LINE_TABLE_BYTES"]

#: the columns a line table may have, by what they hold (the unit is the name's suffix)
LINE_TABLE_COLUMNS = {
    "label": "line name, unique (e.g. P(9))",
    "center": "centre: frequency (center_hz .. center_thz) or vacuum wavelength (center_nm)",
    "std": "standard uncertainty (k = 1) of the centre: std_hz .. std_ghz, std_nm or std_pm",
    "pressure_shift": "optional: shift per pascal, pressure_shift_hz_per_pa (or _pm_per_pa)",
}
#: largest line table read (a table of thousands of lines is a few hundred kB)
MAX_LINE_TABLE_BYTES = 16 * 2**20
#: wavelength units of a line table: metres per unit
_WAVELENGTH_M = {"nm": 1e-9, "pm": 1e-12}


def _column_unit(name: str, stem: str, suffix: str = "") -> tuple[str, float] | None:
    """``(kind, scale)`` of a column ``<stem>_<unit><suffix>``: kind ``"hz"`` with the unit's
    size in Hz, or ``"m"`` with its size in metres; None when the name is not of that stem."""
    lowered = name.strip().lower()
    if not (lowered.startswith(stem + "_") and lowered.endswith(suffix)):
        return None
    unit = lowered[len(stem) + 1 : len(lowered) - len(suffix)]
    for known, exponent in FREQUENCY_UNITS.items():
        if unit == known.lower():
            return "hz", 10.0**exponent
    if unit in _WAVELENGTH_M:
        return "m", _WAVELENGTH_M[unit]
    return None


@dataclass(frozen=True, eq=False)
class ReferenceLines:
    """Reference lines of a gas cell, in increasing frequency.

    Parameters
    ----------
    labels : sequence of str, length L
        Unique line names.
    center_hz : array_like, shape (L,)
        Line centres (Hz), optical (100-1000 THz). At zero pressure when
        ``pressure_shift_hz_per_pa`` is given, else at the conditions of the cell used.
    std_hz : array_like, shape (L,)
        Standard uncertainty (k = 1) of each centre (Hz), > 0. Lines are taken as
        independent.
    pressure_shift_hz_per_pa : None or array_like, shape (L,)
        Shift of each centre with the cell's pressure (Hz/Pa); None when the centres are
        those of the cell at its own pressure.
    source : str
        Where the numbers come from (publication, table, conditions).

    Raises
    ------
    InputError
        For empty, non-finite, non-optical or unsorted-and-duplicate values, a ``std_hz``
        that is not > 0, or labels that are not unique.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import wavemeter as wm
    >>> path = Path(tempfile.mkdtemp()) / "cell.csv"
    >>> rows = ["label,center_nm,std_pm", "line A,1530.0,0.1", "line B,1531.0,0.1"]
    >>> with open(path, "w") as file:
    ...     for row in rows:
    ...         print(row, file=file)
    >>> lines = wm.ReferenceLines.read_csv(path)  # vacuum wavelengths in nm, std in pm
    >>> lines.labels  # in increasing frequency: 1531 nm first
    ('line B', 'line A')
    >>> print([f"{center / 1e12:.4f} THz" for center in lines.center_hz])
    ['195.8148 THz', '195.9428 THz']
    >>> print([f"{std / 1e6:.1f} MHz" for std in lines.std_hz])
    ['12.8 MHz', '12.8 MHz']
    """

    labels: tuple
    center_hz: np.ndarray
    std_hz: np.ndarray
    pressure_shift_hz_per_pa: np.ndarray | None = None
    source: str = ""

    def __post_init__(self):
        labels = tuple(str(label) for label in self.labels)
        center = np.asarray(self.center_hz, dtype=float).reshape(-1)
        std = np.asarray(self.std_hz, dtype=float).reshape(-1)
        if center.size == 0:
            raise InputError("a line table needs at least one line, got none")
        if len(labels) != center.size or std.shape != center.shape:
            raise InputError(
                f"labels, center_hz and std_hz must have one entry per line, got "
                f"{len(labels)}, {center.size} and {std.size}"
            )
        low, high = OPTICAL_BAND_HZ
        if not np.all(np.isfinite(center) & (center > low) & (center < high)):
            raise InputError(
                f"line centres must be optical frequencies ({low / 1e12:g}-{high / 1e12:g} THz), "
                f"got {center[~(np.isfinite(center) & (center > low) & (center < high))][:3]}"
            )
        if not np.all(np.isfinite(std) & (std > 0)):
            raise InputError("std_hz must be finite and > 0 for every line (Hz, k = 1)")
        if len(set(labels)) != len(labels):
            repeated = sorted({label for label in labels if labels.count(label) > 1})
            raise InputError(f"line labels must be unique, repeated: {repeated[:5]}")
        shift = self.pressure_shift_hz_per_pa
        if shift is not None:
            shift = np.asarray(shift, dtype=float).reshape(-1)
            if shift.shape != center.shape or not np.all(np.isfinite(shift)):
                raise InputError("pressure_shift_hz_per_pa must be one finite number per line")
        order = np.argsort(center, kind="stable")
        if np.any(np.diff(center[order]) <= 0):
            raise InputError("two lines have the same centre frequency")
        object.__setattr__(self, "labels", tuple(labels[k] for k in order))
        object.__setattr__(self, "center_hz", center[order])
        object.__setattr__(self, "std_hz", std[order])
        object.__setattr__(
            self, "pressure_shift_hz_per_pa", None if shift is None else shift[order]
        )
        for array in (self.center_hz, self.std_hz, self.pressure_shift_hz_per_pa):
            if array is not None:
                array.setflags(write=False)

    def __len__(self) -> int:
        return self.center_hz.size

    def __repr__(self) -> str:
        low, high = self.center_hz[0], self.center_hz[-1]
        return (
            f"ReferenceLines({len(self)} lines, {low / 1e12:.6f}-{high / 1e12:.6f} THz, "
            f"source={self.source[:60]!r})"
        )

    # ------------------------------------------------------------------ selection
    def take(self, indices) -> ReferenceLines:
        """The lines at some indices (in the table's frequency order)."""
        index = np.asarray(indices, dtype=int).reshape(-1)
        shift = self.pressure_shift_hz_per_pa
        return ReferenceLines(
            labels=tuple(self.labels[k] for k in index),
            center_hz=self.center_hz[index],
            std_hz=self.std_hz[index],
            pressure_shift_hz_per_pa=None if shift is None else shift[index],
            source=self.source,
        )

    def within(self, band_hz) -> ReferenceLines:
        """The lines whose centres lie in ``band_hz = (low, high)`` (Hz), inclusive.

        Raises
        ------
        InputError
            When the band is not two increasing finite frequencies or holds no line.
        """
        low, high = _band(band_hz)
        inside = np.flatnonzero((self.center_hz >= low) & (self.center_hz <= high))
        if inside.size == 0:
            raise InputError(
                f"no line of the table lies in the band {low / 1e12:.6f}-{high / 1e12:.6f} THz "
                f"(the table spans {self.center_hz[0] / 1e12:.6f}-"
                f"{self.center_hz[-1] / 1e12:.6f} THz)",
                parameter="band_hz",
            )
        return self.take(inside)

    def centers_at(self, pressure_pa: float | None) -> np.ndarray:
        """Centres (Hz) in a cell at ``pressure_pa``: the table's centres plus the pressure
        shift; the table's centres when it has no shift or the pressure is None."""
        if pressure_pa is None or self.pressure_shift_hz_per_pa is None:
            return self.center_hz.copy()
        return self.center_hz + self.pressure_shift_hz_per_pa * float(pressure_pa)

    def spacing_hz(self) -> np.ndarray:
        """Distance (Hz) from each line to its nearest neighbour, shape (L,); inf for one line."""
        if len(self) == 1:
            return np.array([np.inf])
        gaps = np.diff(self.center_hz)
        return np.minimum(np.r_[np.inf, gaps], np.r_[gaps, np.inf])

    # ------------------------------------------------------------------ files
    @classmethod
    def read_csv(cls, path) -> ReferenceLines:
        """Read a line table from a CSV file.

        The file has a header row ``label,center_hz,std_hz`` (any frequency unit as the
        suffix: ``center_thz``; or vacuum wavelength ``center_nm`` with ``std_nm`` or
        ``std_pm``), optionally ``pressure_shift_hz_per_pa`` (or ``pressure_shift_pm_per_pa``,
        a wavelength shift); columns in any order. Lines starting with ``#`` before the
        header are the table's source (citation, conditions); blank lines are skipped.

        Parameters
        ----------
        path : str or Path

        Returns
        -------
        ReferenceLines

        Raises
        ------
        FileFormatError
            Naming the file, the line and the field, for a missing or unknown column, a
            value that is not a number or not allowed, a short row, or a file that is not
            text or too large.
        """
        path = Path(path)
        try:
            if path.stat().st_size > MAX_LINE_TABLE_BYTES:
                raise FileFormatError(
                    f"{path}: a line table may have at most {MAX_LINE_TABLE_BYTES} bytes"
                )
            text = path.read_bytes().decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise FileFormatError(f"{path}: not a UTF-8 text file ({exc.reason})") from exc
        return _parse_table(text, str(path))

    def to_csv(self, path) -> None:
        """Write the table as CSV (``label,center_hz,std_hz[,pressure_shift_hz_per_pa]``,
        the source as ``#`` lines), at full float64 precision, atomically."""
        buffer = io.StringIO()
        for line in self.source.splitlines():
            buffer.write(f"# {line}\n")
        writer = csv.writer(buffer, lineterminator="\n")
        header = ["label", "center_hz", "std_hz"]
        shift = self.pressure_shift_hz_per_pa
        if shift is not None:
            header.append("pressure_shift_hz_per_pa")
        writer.writerow(header)
        for k, label in enumerate(self.labels):
            row = [label, repr(float(self.center_hz[k])), repr(float(self.std_hz[k]))]
            if shift is not None:
                row.append(repr(float(shift[k])))
            writer.writerow(row)
        with atomic_path(path) as temporary:
            temporary.write_text(buffer.getvalue(), encoding="utf-8")


def _band(band_hz) -> tuple[float, float]:
    try:
        low, high = (float(value) for value in band_hz)
    except (TypeError, ValueError):
        raise InputError(
            f"band_hz must be two frequencies (low, high) in Hz, got {shown(band_hz)}",
            parameter="band_hz",
        ) from None
    if not (math.isfinite(low) and math.isfinite(high) and 0 < low < high):
        raise InputError(
            f"band_hz must be two finite frequencies 0 < low < high (Hz), got {shown(band_hz)}",
            parameter="band_hz",
        )
    return low, high


def _columns(header: list[str], where: str) -> dict:
    """Index and unit of each column a line table needs, from its header."""
    found: dict = {}
    for index, name in enumerate(header):
        key = name.strip().lower()
        if key == "label":
            found.setdefault("label", (index, None))
            continue
        for stem, suffix in (("center", ""), ("std", ""), ("pressure_shift", "_per_pa")):
            unit = _column_unit(key, stem, suffix)
            if unit is not None:
                if stem in found:
                    raise FileFormatError(f"{where}: two columns give the {stem}: {header}")
                found[stem] = (index, unit)
                break
        else:
            raise FileFormatError(
                f"{where}: unknown column {name.strip()!r}; a line table has the columns "
                + "; ".join(f"{k}: {v}" for k, v in LINE_TABLE_COLUMNS.items())
            )
    missing = [name for name in ("label", "center", "std") if name not in found]
    if missing:
        raise FileFormatError(
            f"{where}: missing column(s) {', '.join(missing)}; the header must name label, "
            "center_<unit> and std_<unit> (e.g. label,center_hz,std_hz)"
        )
    return found


def _parse_table(text: str, name: str) -> ReferenceLines:
    source: list[str] = []
    rows: list[tuple[int, list[str]]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if not rows:
                source.append(stripped[1:].strip())
            continue
        rows.append((number, next(csv.reader([line]))))
    if not rows:
        raise FileFormatError(f"{name}: no header row (label,center_hz,std_hz) and no lines")
    header_line, header = rows[0]
    columns = _columns(header, f"{name} line {header_line}")
    if len(rows) == 1:
        raise FileFormatError(f"{name}: the table has a header but no lines")
    labels, center, std, shift = [], [], [], []
    for number, cells in rows[1:]:
        if len(cells) != len(header):
            raise FileFormatError(
                f"{name} line {number}: {len(cells)} fields, the header has {len(header)}"
            )

        def value(stem: str, number=number, cells=cells) -> float:
            index, _ = columns[stem]
            field = header[index].strip()
            try:
                number_value = float(cells[index])
            except ValueError:
                raise FileFormatError(
                    f"{name} line {number}, field {field!r}: {cells[index]!r} is not a number"
                ) from None
            if not math.isfinite(number_value):
                raise FileFormatError(
                    f"{name} line {number}, field {field!r}: {cells[index]!r} is not finite"
                )
            return number_value

        label = cells[columns["label"][0]].strip()
        if not label:
            raise FileFormatError(f"{name} line {number}, field 'label': empty")
        frequency = _to_hz(value("center"), columns["center"][1], name, number, header)
        labels.append(label)
        center.append(frequency)
        std.append(_uncertainty_hz(value("std"), columns["std"][1], frequency))
        if "pressure_shift" in columns:
            shift.append(
                _uncertainty_hz(
                    value("pressure_shift"), columns["pressure_shift"][1], frequency, signed=True
                )
            )
        field_std = header[columns["std"][0]].strip()
        if not std[-1] > 0:
            raise FileFormatError(f"{name} line {number}, field {field_std!r}: must be > 0")
    try:
        return ReferenceLines(
            labels=labels,
            center_hz=center,
            std_hz=std,
            pressure_shift_hz_per_pa=shift if "pressure_shift" in columns else None,
            source="\n".join(source),
        )
    except InputError as exc:
        raise FileFormatError(f"{name}: {exc}") from exc


def _to_hz(number: float, unit: tuple[str, float], name: str, line: int, header) -> float:
    kind, scale = unit
    if kind == "hz":
        frequency = number * scale
    else:
        frequency = SPEED_OF_LIGHT_M_S / (number * scale) if number > 0 else -1.0
    low, high = OPTICAL_BAND_HZ
    if not low < frequency < high:
        raise FileFormatError(
            f"{name} line {line}, field 'center': {shown(number)} is not an optical line centre "
            f"({low / 1e12:g}-{high / 1e12:g} THz) in the header's unit"
        )
    return frequency


def _uncertainty_hz(number: float, unit: tuple[str, float], center_hz: float, signed=False):
    """An uncertainty or shift in Hz from a frequency or wavelength value: a wavelength
    interval ``d lambda`` is ``c d lambda / lambda^2 = f^2 d lambda / c`` in frequency, and a
    positive wavelength shift is a negative frequency shift."""
    kind, scale = unit
    if kind == "hz":
        return number * scale
    size = center_hz**2 * number * scale / SPEED_OF_LIGHT_M_S
    return -size if signed else size
