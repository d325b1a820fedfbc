"""`wavemeter calibrate`: learn a calibration from a sweep file."""

from __future__ import annotations

from pathlib import Path

import click

from ..atomic import check_output
from ..exceptions import InputError
from ..progress import busy
from ._common import (
    FORCE,
    FSR,
    PORT_PHASES,
    QUIET,
    about,
    column_options,
    column_request,
    out_option,
    port_phases_rad,
    printable,
    read,
    say,
    setting,
)
from ._streams import is_stdio, output_path


def _fit(options: dict, table, phases):
    from ..calibration.baselines import ConventionalCalibrator
    from ..calibration.learned import Calibrator
    from ..calibration.set import CalibrationSet

    fsr, tolerance, method = options["fsr"], options["fsr_tolerance"], options["method"]
    retrieval = options["retrieval"]
    if method != "learned" and retrieval != "pinv":
        raise InputError(f"--retrieval {retrieval} needs --method learned, got --method {method}")
    if method == "learned":
        calibrator = Calibrator(fsr_hz=fsr, fsr_tolerance=tolerance, retrieval=retrieval)
    else:
        calibrator = ConventionalCalibrator(fsr_hz=fsr, port_phases_rad=phases)
    if options["per_fsr"]:
        calibrator = CalibrationSet(fsr, tolerance, window=calibrator)
    description = printable(f"calibrating on {table.source}")
    with busy(description, quiet=options["quiet"]), about(table.source):
        return calibrator.fit(table.powers_w, table.x_hz, table.monitor_w, list(table.port_names))


def _check_calibration_output(out_path, sweep, force: bool) -> None:
    """Before any work: the output is not the sweep, may be replaced, and is JSON."""
    check_output(out_path, inputs=(sweep,), force=force)
    if not is_stdio(out_path) and Path(out_path).suffix.lower() != ".json":
        raise InputError(
            f"cannot write {out_path}: a calibration file is JSON; give a name ending in "
            ".json (e.g. chip.wmcal.json), or - for stdout"
        )


def _metadata(table) -> dict:
    """What the calibration was read from, kept in the calibration file."""
    temperature = table.temperature_k
    return {
        "sweep_file": str(table.source),
        "x_column": table.x_column,
        "x_unit": table.x_unit,
        "port_columns": list(table.port_names),
        "port_units": list(table.port_units),
        "monitor_column": table.monitor_column,
        "temperature_column": table.temperature_column,
        "temperature_k_range": None
        if temperature is None
        else [float(temperature.min()), float(temperature.max())],
        "rows": table.n_rows,
        "dropped_rows": table.dropped_rows,
    }


@click.command()
@click.argument("sweep", type=click.Path(dir_okay=False))
@out_option("Calibration file to write: JSON, e.g. chip.wmcal.json ('-' for stdout).")
@setting("--fsr", "50GHz", FSR, "Design FSR: 50GHz, '49.69 GHz'; a bare number is in Hz (5e10).")
@setting(
    "--fsr-tolerance",
    0.2,
    click.FloatRange(0, 1, min_open=True, max_open=True),
    "Relative half width of the FSR search (learned method).",
)
@click.option(
    "--method",
    type=click.Choice(("learned", "conventional")),
    default="learned",
    show_default=True,
    help="Learned linear map (paper) or the conventional ideal-map method.",
)
@click.option(
    "--retrieval",
    type=click.Choice(("pinv", "ml")),
    default="pinv",
    show_default=True,
    help="Phase retrieval of the learned method: pseudo-inverse (paper) or cone-constrained "
    "maximum likelihood (reaches the Cramer-Rao bound also for ill-conditioned maps).",
)
@PORT_PHASES
@click.option(
    "--per-fsr",
    is_flag=True,
    help="Calibrate each FSR of a multi-FSR sweep on its own (a calibration set).",
)
@column_options()
@FORCE
@QUIET
def calibrate(sweep, out_path, port_phases_deg, force, **options):
    """Learn a calibration from a sweep of known frequencies.

    SWEEP is a CSV/TSV, HDF5, MAT, NPZ or Parquet file ('-' for stdin) with a frequency
    or wavelength column and three or more port columns. The calibration file must not
    exist unless --force is given; with -o - it goes to stdout and the summary to stderr.

    \b
    Example:
      wavemeter calibrate sweep.csv -o chip.wmcal.json --fsr 50GHz
      wavemeter calibrate lab.csv -o chip.wmcal.json --fsr '49.69 GHz' \\
          --x 'Wavelength (nm)' --ports 'Port 1 [dBm]','Port 2 [dBm]','Port 3 [dBm]'
    """
    from ..calibration.files import save_calibration

    _check_calibration_output(out_path, sweep, force)
    request = column_request(options)
    quiet = options["quiet"]
    table = read(
        sweep, request, need_x=True, drop_invalid=options["drop_invalid"], quiet=quiet
    ).valid_only()
    calibration = _fit(options, table, port_phases_rad(port_phases_deg))
    with output_path(out_path) as target:
        save_calibration(calibration, target, _metadata(table))
    to_stderr = is_stdio(out_path)
    say(
        quiet,
        f"calibrated {table.source}: {table.n_rows} rows, axis {table.x_column} "
        f"({table.x_unit}), ports {', '.join(table.port_names)}"
        + (f", monitor {table.monitor_column}" if table.monitor_column else ""),
        err=to_stderr,
    )
    say(quiet, calibration.summary().text, err=to_stderr)
    say(quiet, f"wrote {'the calibration to stdout' if to_stderr else out_path}", err=to_stderr)


command = calibrate
