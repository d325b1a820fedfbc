"""`wavemeter info`: what a calibration file holds.

Everything printed comes from the file, so it passes through :func:`printable` first: a
crafted port name or metadata value cannot send escape sequences to the terminal. The
fit report (``summary().text``) holds a thermal calibration's rates with their standard
errors, its reference temperature, calibrated range and unambiguous bias-rate range; the
metadata says where each sweep file's temperature came from. A wide-band calibration adds
its orders and parameter count, its phase coefficients with their standard errors, how the
orders were chosen (the cross-validation curve) and the residual phase across the band
(``diagnostics_["wideband"]``). A cascade calibration adds a line per stage (FSR, ports,
orders, median standard deviation), per hand-over (FSR ratio and the largest usable one,
margin in standard deviations, predicted wrong-order rate, wrong orders on the sweep) and
the coarsest stage's edge margin (``diagnostics_["cascade"]``).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import click

from ..exceptions import FileFormatError
from ..report.formatting import PHASE_COEFFICIENT_NAMES, scientific_with_error
from ._common import cascade_lines, printable

#: extensions of the data files the readers take (sweeps, readings), never calibrations
DATA_EXTENSIONS = frozenset(
    {".csv", ".tsv", ".txt", ".dat", ".h5", ".hdf5", ".hdf", ".mat", ".npz", ".npy", ".parquet"}
)
#: leading bytes of binary data formats: HDF5 (and MAT v7.3), MAT v5, NPZ (zip), Parquet, NPY
DATA_SIGNATURES = (b"\x89HDF\r\n\x1a\n", b"MATLAB 5.0", b"PK\x03\x04", b"PAR1", b"\x93NUMPY")
PEEK_BYTES = 4096
LABEL_WIDTH = 17
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_DELIMITERS = re.compile(r"[,;\t]")
#: metadata entries of the sweep line (shown there when the file names its sweep)
_SWEEP = {"sweep_file", "rows", "rows_per_file", "x_column", "x_unit", "port_units"}
#: metadata entries with lines of their own (the rest follow, one per line)
_OWN_LINES = {
    "port_columns",
    "monitor_column",
    "temperature_column",
    "temperature_k_range",
    "temperature_k_given",
}


CV_HEADER = ("phase order", "map order", "parameters", "held-out RMS MHz")


def _line(label: str, text: str) -> str:
    return printable(f"{label:<{LABEL_WIDTH}}{text}")


def _looks_like_table(head: bytes) -> bool:
    """A text file whose first non-comment line is a header and the next a row of numbers."""
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = head.decode("latin-1")
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")]
    if len(lines) < 2 or not _DELIMITERS.search(lines[0]):
        return False
    header = [cell.strip() for cell in _DELIMITERS.split(lines[0])]
    row = [cell.strip() for cell in _DELIMITERS.split(lines[1])]
    return (
        len(header) == len(row) >= 2
        and not all(_NUMBER.match(cell) for cell in header)
        and all(_NUMBER.match(cell) for cell in row)
    )


def is_data_file(path) -> bool:
    """Whether ``path`` is a data file (sweep or readings) rather than a calibration.

    Judged by a known data extension, a binary data signature, or a text table (a header
    row followed by a row of numbers) in the first ``PEEK_BYTES`` bytes.
    """
    path = Path(path)
    if path.suffix.lower() in DATA_EXTENSIONS:
        return True
    try:
        with open(path, "rb") as stream:
            head = stream.read(PEEK_BYTES)
    except OSError:
        return False
    return head.startswith(DATA_SIGNATURES) or _looks_like_table(head)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _temperatures_text(values) -> str:
    if isinstance(values, list) and values and all(map(_is_number, values)):
        return ", ".join(f"{value:.6g}" for value in values) + " K"
    return "?"


def _sweep_files(value) -> str:
    if isinstance(value, list):
        return ", ".join(map(str, value))
    return str(value)


def metadata_lines(metadata: dict) -> list[str]:
    """Every entry of a calibration file's metadata: where the sweep came from and how
    its columns were read, then any other notes."""
    lines = []
    shown = set(_OWN_LINES)
    if metadata.get("sweep_file") is not None:
        shown |= _SWEEP
        units = metadata.get("port_units")
        if isinstance(units, list) and units and all(isinstance(u, list) for u in units):
            units = [unit for file_units in units for unit in file_units]  # one list per file
        unit_text = (
            ", ".join(sorted({str(unit or "relative") for unit in units}))
            if isinstance(units, list)
            else "?"
        )
        per_file = metadata.get("rows_per_file")
        rows = str(metadata.get("rows"))
        if isinstance(per_file, list):
            rows += f" = {' + '.join(map(str, per_file))}"
        lines.append(
            _line(
                "sweep",
                f"{_sweep_files(metadata['sweep_file'])} ({rows} rows, axis "
                f"{_sweep_files(metadata.get('x_column'))} in "
                f"{_sweep_files(metadata.get('x_unit'))}, ports in {unit_text})",
            )
        )
    columns = metadata.get("port_columns")
    if isinstance(columns, list) and columns and all(isinstance(c, list) for c in columns):
        lines.append(_line("port columns", "; ".join(", ".join(map(str, c)) for c in columns)))
    elif isinstance(columns, list):
        lines.append(_line("port columns", ", ".join(map(str, columns))))
    lines.append(_line("monitor column", _sweep_files(metadata.get("monitor_column") or "none")))
    span = metadata.get("temperature_k_range")
    given = metadata.get("temperature_k_given")
    if isinstance(span, list) and len(span) == 2 and all(map(_is_number, span)):
        source = (
            f"given per file: {_temperatures_text(given)}"
            if isinstance(given, list)
            else f"column {_sweep_files(metadata.get('temperature_column'))}"
        )
        lines.append(_line("temperature", f"{span[0]:.6g} to {span[1]:.6g} K ({source})"))
    else:
        lines.append(_line("temperature", "not recorded"))
    for key, value in metadata.items():
        if key not in shown:
            lines.append(_line(str(key), value))
    return lines


def _number(value) -> float | None:
    """A finite number of a calibration file, else None (a file may be hand-edited)."""
    return float(value) if _is_number(value) and math.isfinite(value) else None


def _coefficient_lines(record: dict) -> list[str]:
    """One line per phase coefficient ``c_i`` (s^i) with its standard error."""
    values = record.get("phase_coefficients_s")
    errors = record.get("phase_coefficients_std_s")
    if not isinstance(values, list):
        return []
    if not isinstance(errors, list) or len(errors) != len(values):
        errors = [None] * len(values)
    lines = []
    for order, (value, error) in enumerate(zip(values, errors, strict=True), start=1):
        number = _number(value)
        if number is None:
            lines.append(_line(f"phase c{order}", "?"))
            continue
        unit = "s" if order == 1 else f"s^{order}"
        name = PHASE_COEFFICIENT_NAMES.get(order, f"order {order}")
        text = scientific_with_error(number, _number(error), " +- ")
        lines.append(_line(f"phase c{order}", f"{text} {unit} ({name})"))
    return lines


def _cross_validation_lines(orders: dict) -> list[str]:
    """How the orders were chosen, and the table of the candidates scored."""
    lines = [_line("orders", str(orders.get("reason", orders.get("method", "?"))))]
    candidates = orders.get("candidates")
    if not isinstance(candidates, list) or not candidates:
        return lines
    widths = [len(title) + 2 for title in CV_HEADER]
    lines.append(
        printable("  " + "".join(f"{t:>{w}}" for t, w in zip(CV_HEADER, widths, strict=True)))
    )
    for candidate in candidates:
        if not isinstance(candidate, dict):
            continue
        rms = _number(candidate.get("cv_rms_hz"))
        cells = (
            str(candidate.get("phase_order", "?")),
            str(candidate.get("map_order", "?")),
            str(candidate.get("parameters", "?")),
            "?" if rms is None else f"{rms / 1e6:.4f}",
        )
        row = "".join(f"{cell:>{w}}" for cell, w in zip(cells, widths, strict=True))
        lines.append(
            printable("  " + row + ("  <- chosen" if candidate.get("chosen") is True else ""))
        )
    return lines


def _residual_phase_line(rows) -> list[str]:
    """The RMS residual phase per FSR window: its range over the band and the worst window."""
    if not isinstance(rows, list):
        return []
    windows = [
        (rms, row)
        for row in rows
        if isinstance(row, dict) and (rms := _number(row.get("rms_rad"))) is not None
    ]
    if not windows:
        return [_line("residual phase", "not recorded")]
    lowest = min(rms for rms, _ in windows)
    highest, worst = max(windows, key=lambda pair: pair[0])
    center, mean = _number(worst.get("center_hz")), _number(worst.get("mean_rad"))
    where = "?" if center is None else f"{center / 1e12:.6f} THz"
    mean_text = "?" if mean is None else f"{mean * 1e3:.3g}"
    return [
        _line(
            "residual phase",
            f"RMS {lowest * 1e3:.3g} to {highest * 1e3:.3g} mrad over {len(windows)} FSR "
            f"windows; largest in the window at {where} (mean {mean_text} mrad, "
            f"{worst.get('readings', '?')} readings)",
        )
    ]


def wideband_lines(diagnostics) -> list[str]:
    """What ``diagnostics_["wideband"]`` of a wide-band calibration holds, as lines: orders
    and parameter count, the phase coefficients with standard errors, how the orders were
    chosen (cross-validation curve), the residual phase across the band. None for other
    calibrations."""
    record = diagnostics.get("wideband") if isinstance(diagnostics, dict) else None
    if not isinstance(record, dict):
        return []
    lines = [
        _line(
            "wide band",
            f"phase order {record.get('phase_order', '?')}, map order "
            f"{record.get('map_order', '?')}, {record.get('n_parameters', '?')} fitted parameters",
        ),
        *_coefficient_lines(record),
    ]
    orders = record.get("orders")
    if isinstance(orders, dict):
        lines += _cross_validation_lines(orders)
    return lines + _residual_phase_line(record.get("residual_phase"))


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
def info(calibration_file):
    """Print everything a calibration file holds: settings, fitted values, diagnostics.

    \b
    Example:
      wavemeter info chip.wmcal.json
    """
    from ..calibration.files.document import read_calibration_file

    try:
        content = read_calibration_file(calibration_file)
    except FileFormatError as exc:
        path = Path(calibration_file)
        if path.exists() and is_data_file(path):
            raise FileFormatError(
                printable(
                    f"{calibration_file} is a data file, not a calibration file; calibrate it "
                    f"with `wavemeter calibrate {calibration_file} -o cal.wmcal.json`"
                )
            ) from exc
        raise FileFormatError(printable(str(exc))) from exc
    click.echo(
        printable(
            f"{calibration_file}: wavemeter {content.wavemeter_version} calibration "
            f"(schema {content.schema_version}), created {content.created_utc}"
        )
    )
    click.echo(printable(content.calibrator.summary().text))
    diagnostics = getattr(content.calibrator, "diagnostics_", None)
    model_lines = wideband_lines(diagnostics) + cascade_lines(diagnostics)
    if model_lines:
        click.echo("\n".join(model_lines))
    click.echo("\n".join(metadata_lines(content.metadata)))


command = info
