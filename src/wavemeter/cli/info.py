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

import re
from pathlib import Path

import click

from ..exceptions import FileFormatError
from ._common import printable

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
#: labels of the other entries the package writes (a user's own keep their names)
_LABELS = {
    "dropped_rows": "dropped rows",
    "dark_file": "dark readings",
    "reanchor_file": "re-anchored on",
    "sweep_file": "sweep",
}
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


def _options_text(record) -> str:
    """What ``calibrate_options`` adds to the settings line: the method, per FSR or not,
    the columns asked for, invalid rows, the dark readings and the temperatures given."""
    if not isinstance(record, dict):
        return str(record)
    request = record.get("request") if isinstance(record.get("request"), dict) else {}
    asked = ", ".join(f"{key} {value}" for key, value in request.items() if value)
    dark = record.get("dark_file") or record.get("dark_w")
    parts = [
        f"method {record.get('method')}",
        f"per FSR {'yes' if record.get('per_fsr') else 'no'}",
        f"columns {asked or 'found by name'}",
        f"invalid rows {'skipped' if record.get('drop_invalid') else 'refused'}",
        f"dark readings {dark}" if dark else "no dark readings",
    ]
    if record.get("temperature_k"):
        parts.append(f"temperatures given {_temperatures_text(record['temperature_k'])}")
    return "; ".join(parts)


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
    if "crlb_rms_hz" in metadata:
        crlb = metadata["crlb_rms_hz"]
        text = (
            f"{crlb / 1e6:.5g} MHz RMS (the Cramer-Rao bound)"
            if _is_number(crlb)
            else "none (the method states no bound)"
        )
        lines.append(_line("sweep CRLB", text))
        shown.add("crlb_rms_hz")
    if "calibrate_options" in metadata:
        lines.append(_line("options", _options_text(metadata["calibrate_options"])))
        shown.add("calibrate_options")
    for key, value in metadata.items():
        if key not in shown:
            label = _LABELS.get(key, str(key))
            lines.append(_line(label, "none" if value is None else _sweep_files(value)))
    return lines


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
    click.echo("\n".join(metadata_lines(content.metadata)))


command = info
