"""A calibration job's reference cell: its options checked, its line table read, fit keywords.

A sweep file may carry a gas cell's channel recorded beside the ports (a column named by
``reference_column``). With the cell's line table (``reference_lines``: a file that
:meth:`wavemeter.ReferenceLines.read_csv` reads, or a table) the job fits a calibrator
that offers the ``"reference_cell"`` capability with the cell's ``fit`` keywords, so the
calibration is absolute; with ``band_hz`` too, a sweep file without a frequency column is
self-calibrated from the lines. No table ships: the lines come from the user's file.
Theory: the docs' page on absolute accuracy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..reference import ReferenceLines

__all__ = [
    "CELL_OPTIONS",
    "cell_channel",
    "cell_keywords",
    "cell_record",
    "check_axes",
    "check_cell_options",
]

#: the options of :class:`~wavemeter.jobs.CalibrateOptions` that describe the cell
CELL_OPTIONS = (
    "reference_column",
    "reference_lines",
    "band_hz",
    "reference_pressure_pa",
    "reference_pressure_std_pa",
    "axis_error_hz",
)


def check_cell_options(options, calibrator, methods_offering) -> None:
    """Before any reading: the channel and the table given together, the other cell options
    only with them, and a calibrator that takes a reference cell in its fit.

    Parameters
    ----------
    options : CalibrateOptions
    calibrator
        The unfitted calibrator the options make.
    methods_offering : callable
        ``methods_offering(capability) -> list of tags``, for the message.

    Raises
    ------
    InputError
        Naming the option at fault.
    """
    column, lines = options.reference_column, options.reference_lines
    if column is None and lines is None:
        extras = [name for name in CELL_OPTIONS[2:] if getattr(options, name) not in (None, 0.0)]
        if extras:
            raise InputError(
                f"{extras[0]} describes a reference cell, but no reference_column and "
                "reference_lines were given: give both, or leave it out",
                parameter=extras[0],
            )
        return
    if column is None or lines is None:
        missing = "reference_column" if column is None else "reference_lines"
        raise InputError(
            "a reference cell needs its channel (reference_column, a column of the sweep "
            f"file) and its line table (reference_lines, a file); {missing} is missing",
            parameter=missing,
        )
    if "reference_cell" not in calibrator.capabilities:
        raise InputError(
            f"method {options.method!r} cannot take a reference cell in its fit; methods that "
            f"can: {', '.join(methods_offering('reference_cell'))}",
            parameter="method",
        )


def cell_channel(table, column: str, drop_invalid: bool):
    """The valid rows' cell channel (float); rows where it is not finite are skipped with
    ``drop_invalid``, else refused naming the file's line."""
    channel = np.asarray(table.kept[column], dtype=float)
    bad = np.flatnonzero(~np.isfinite(channel))
    if bad.size and not drop_invalid:
        raise InputError(
            f"{table.source}: {column} is NaN, empty or inf on "
            f"{table.row_label(int(table.row_index[bad[0]]))} ({bad.size} row(s)); fix or "
            "delete them, or skip invalid rows (drop_invalid)",
            parameter="reference_column",
        )
    if bad.size:
        keep = np.isfinite(channel)
        return table.select(keep), channel[keep]
    return table, channel


def check_axes(tables) -> None:
    """The sweep files of one calibration have a frequency column in all or none."""
    if len({table.x_hz is None for table in tables}) > 1:
        raise InputError(
            "some sweep files have a frequency column and some none; the sweeps of one "
            "calibration need one in every file or in none",
            parameter="x",
        )


def _lines(reference_lines) -> ReferenceLines:
    """The table given, or read from its file (InputError naming the file)."""
    if isinstance(reference_lines, ReferenceLines):
        return reference_lines
    if not isinstance(reference_lines, (str, Path)):
        raise InputError(
            "reference_lines must be a line table file (label,center_hz,std_hz) or a "
            f"wavemeter.ReferenceLines, got {type(reference_lines).__name__}",
            parameter="reference_lines",
        )
    path = Path(reference_lines)
    if not path.is_file():
        raise InputError(
            f"{path}: no such line table file; give the cell's line table as a CSV file "
            "with the header label,center_hz,std_hz",
            parameter="reference_lines",
        )
    return ReferenceLines.read_csv(path)


def cell_keywords(options, channel) -> dict:
    """The reference cell's ``fit`` keywords: the channel (one reading per sweep reading),
    the table, the band, the pressure and the recorded axis's error bound, where given."""
    keywords = {
        "reference_transmission": np.asarray(channel, dtype=float),
        "reference_lines": _lines(options.reference_lines),
        "band_hz": options.band_hz,
        "reference_pressure_pa": options.reference_pressure_pa,
        "reference_pressure_std_pa": options.reference_pressure_std_pa,
        "axis_error_hz": options.axis_error_hz,
    }
    return {name: value for name, value in keywords.items() if value is not None}


def cell_record(options) -> dict | None:
    """What a calibration file keeps of the cell's options (JSON-ready); None without a
    cell. The table's file by its name as given; a table given as an object by its source."""
    if options.reference_column is None:
        return None
    lines = options.reference_lines
    return {
        "reference_column": options.reference_column,
        "reference_lines": lines.source if isinstance(lines, ReferenceLines) else str(lines),
        "band_hz": None if options.band_hz is None else [float(v) for v in options.band_hz],
        "reference_pressure_pa": options.reference_pressure_pa,
        "reference_pressure_std_pa": float(options.reference_pressure_std_pa),
        "axis_error_hz": options.axis_error_hz,
    }
