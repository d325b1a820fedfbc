"""`wavemeter reanchor`: correct a calibration's bias phase (and delay) from reference lines.

Readings of one or more lines of known frequency (a reference laser, a gas-cell line)
re-anchor a learned calibration, single or per FSR, or a thermal one, as
:mod:`wavemeter.calibration.models.reanchor` describes; the result is a new calibration file with
the original's metadata and ``reanchor_file``, the readings' file. A calibration that needs
the chip temperature (``"temperature_k"`` in its ``requires``) gets it from the readings'
temperature column or ``--temperature-k``.
"""

from __future__ import annotations

import click

from ..exceptions import InputError
from ..progress import busy
from ._common import (
    FORCE,
    QUIET,
    about,
    check_calibration_output,
    check_ports,
    column_options,
    column_request,
    fsr_text,
    out_option,
    printable,
    read,
    read_calibration,
    say,
)
from ._params import OPTICAL_FREQUENCY
from ._streams import is_stdio, output_path
from ._temperature import (
    check_temperature_options,
    needs_temperature,
    reading_temperature_k,
    temperature_k_option,
)

#: reference lines listed by frequency in the summary, at most
LINES_SHOWN = 8


def _check_frequency_options(frequency_hz, x_column, x_unit) -> None:
    """Exactly one of ``--frequency`` and ``--x``; ``--x-unit`` only with ``--x``."""
    if (frequency_hz is None) == (x_column is None):
        raise InputError(
            "give the readings' known frequency with --frequency VALUE (one line for the "
            "file) or --x COL (a frequency or wavelength per row), exactly one of the two"
        )
    if x_column is None and x_unit is not None:
        raise InputError("--x-unit is the unit of --x COL; with --frequency it has no use")


def _check_line(check: dict) -> str:
    """How the reference readings scattered: the verdict and the largest scatter ratio."""
    tested = [line for line in check["lines"] if line["p_value"] is not None]
    if not tested:
        return f"reference check {check['verdict']} (no line with two readings)"
    ratio = max(line["scatter_ratio"] for line in tested)
    return (
        f"reference check {check['verdict']} (scatter {ratio:.3g} times the calibration's "
        f"noise at most, p = {check['p_value']:.3g})"
    )


def _change_lines(record: dict) -> list[str]:
    """What one re-anchoring record changed: phase shift, delay; the reference check."""
    lines = [
        f"phase shift {record['phase_shift_rad']:+.6f} rad (std "
        f"{record['phase_shift_std_rad']:.2g} rad)"
    ]
    if record.get("reference_check") is not None:
        lines.append(_check_line(record["reference_check"]))
    if record["delay_change_s"] is None:
        lines.append("delay kept")
    else:
        lines.append(
            f"delay change {record['delay_change_s']:+.4g} s (std "
            f"{record['delay_change_std_s']:.2g} s)"
        )
    return lines


def summary_lines(calibration) -> list[str]:
    """What re-anchoring changed, from ``diagnostics_["reanchor"]`` of the result: lines and
    readings, then the phase shift and delay (per window for a calibration set)."""
    record = calibration.diagnostics_["reanchor"]
    shown = record["lines_hz"][:LINES_SHOWN]
    lines_thz = ", ".join(f"{line_hz / 1e12:.6f}" for line_hz in shown)
    more = len(record["lines_hz"]) - len(shown)
    if more:
        lines_thz += f", ... ({more} more)"
    lines = [f"{record['readings']} readings of {len(record['lines_hz'])} line(s): {lines_thz} THz"]
    if record.get("temperature_k") is not None:
        lines.append(f"at a mean chip temperature of {record['temperature_k']:.6g} K")
    windows = record.get("windows")
    if windows is None:
        lines += _change_lines(record)
        if record["delay_change_s"] is not None:
            lines.append(f"FSR now {fsr_text(calibration.fsr_hz_)}")
        return lines
    for number, window in enumerate(windows):
        source = window["interpolated_from"]
        origin = f" (interpolated from window(s) {', '.join(map(str, source))})" if source else ""
        lines.append(f"window {number}: {', '.join(_change_lines(window))}{origin}")
    return lines


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("readings", type=click.Path(dir_okay=False))
@out_option("Calibration file to write: JSON, e.g. chip-today.wmcal.json ('-' for stdout).")
@click.option(
    "--frequency",
    "frequency_hz",
    type=OPTICAL_FREQUENCY,
    help="Known frequency of every reading (one line), 193.4THz or 1550nm; a bare number is "
    "in Hz. Or --x COL.",
)
@temperature_k_option(
    "Chip temperature of every reading, for a thermal calibration, instead of a column: "
    "293.15 (K), 293.15K, 20C."
)
@column_options()
@FORCE
@QUIET
def reanchor(calibration_file, readings, out_path, frequency_hz, temperature_k, force, **options):
    """Re-anchor a calibration to readings of reference lines of known frequency.

    The chip's bias phase moves with temperature and age; readings of one or more lines
    of known frequency measure the change, and of lines spread over the FSR also a delay
    change. Give the frequency with --frequency (one line for the file) or --x COL (per
    row, unit from the name or --x-unit). Needs a learned calibration, single or per FSR
    (a window without lines gets its shift interpolated), or a thermal one, which also
    needs the chip temperature of each reading: a temperature column (found by name with
    its unit, or --temperature COL) or --temperature-k for the file. The readings of each
    line must scatter like one line at the calibration's noise (an F test): readings far
    beyond it (a sweep or a test file given one --frequency) are refused, a line read with
    more scatter than the calibration's noise is warned; the check is kept in the file. The
    new file keeps the original's metadata; it must not exist unless --force is given, and
    is never CAL or READINGS.

    \b
    Example:
      wavemeter reanchor chip.wmcal.json hcn.csv --frequency 193.4THz -o chip-today.wmcal.json
      wavemeter reanchor chip.wmcal.json lines.csv --x wavelength_nm -o chip-today.wmcal.json
      wavemeter reanchor thermal.wmcal.json hcn.csv --frequency 193.4THz --temperature-k 25C \\
          -o thermal-today.wmcal.json
    """
    from ..calibration.files.document import save_calibration

    quiet = options["quiet"]
    x_column = options["x_column"]
    _check_frequency_options(frequency_hz, x_column, options["x_unit"])  # before any work
    check_calibration_output(out_path, (calibration_file, readings), force)
    content = read_calibration(calibration_file)
    calibration = content.calibrator
    if "reanchor" not in calibration.capabilities:
        from ..jobs.calibrator import methods_offering

        raise InputError(
            f"{calibration_file}: a {calibration.method_label} calibration cannot be "
            "re-anchored (no 'reanchor' among its capabilities); the methods that can: "
            f"{', '.join(methods_offering('reanchor'))}"
        )
    check_temperature_options(
        calibration, calibration_file, column=options["temperature_column"], given=temperature_k
    )
    thermal = needs_temperature(calibration)
    request = column_request(options)
    table = read(
        readings,
        request,
        need_x=x_column is not None,
        drop_invalid=options["drop_invalid"],
        quiet=quiet,
        temperature=(x_column is not None) if not thermal else temperature_k is None,
    ).valid_only()
    check_ports(calibration, calibration_file, table, explicit=request.ports is not None)
    known_hz = table.x_hz if frequency_hz is None else frequency_hz
    temperature = reading_temperature_k(calibration, calibration_file, table, temperature_k)
    if temperature is None:
        temperature = table.temperature_k
    description = printable(f"re-anchoring on {table.source}")
    with busy(description, quiet=quiet), about(table.source):
        anchored = calibration.reanchor(table.powers_w, known_hz, temperature_k=temperature)
    metadata = {**content.metadata, "reanchor_file": str(table.source)}
    with output_path(out_path) as target:
        save_calibration(anchored, target, metadata)
    to_stderr = is_stdio(out_path)
    say(quiet, f"re-anchored {calibration_file} on {table.source}", err=to_stderr)
    for line in summary_lines(anchored):
        say(quiet, line, err=to_stderr)
    say(quiet, f"wrote {'the calibration to stdout' if to_stderr else out_path}", err=to_stderr)


command = reanchor
