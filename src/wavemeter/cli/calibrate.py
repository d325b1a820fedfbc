"""`wavemeter calibrate`: learn a calibration from a sweep file.

Dark readings (``--dark FILE`` averaged per port, or ``--dark-w``) are subtracted from the
sweep and kept in the calibration. With ``--strict`` a :class:`CalibrationWarning` of the
fit is an error: nothing is written and the exit code is 3.
"""

from __future__ import annotations

import contextlib

import click
import numpy as np

from ..exceptions import InputError, recorded_calibration_warnings
from ..io import port_key
from ..progress import busy
from ._common import (
    FORCE,
    FSR,
    PORT_PHASES,
    QUIET,
    about,
    check_calibration_output,
    column_options,
    column_request,
    out_option,
    port_phases_rad,
    printable,
    read,
    say,
    setting,
)
from ._params import OFFSETS
from ._streams import STDIN_LABEL, is_stdio, output_path
from .app import WarningsRefused


@contextlib.contextmanager
def _refused_if(strict: bool):
    """With ``strict``, the block's :class:`CalibrationWarning` s are collected instead of
    shown and raised together after it as :class:`WarningsRefused`; other warnings are
    shown as usual."""
    if not strict:
        yield
        return
    with recorded_calibration_warnings() as refused:
        yield
    if refused:
        raise WarningsRefused(refused, "--strict: no calibration written")


def _port_list(table) -> str:
    return ", ".join(table.port_names)


def _dark_w(options: dict, request, sweep_table) -> np.ndarray | None:
    """Per-port dark readings (W) from ``--dark FILE`` (averaged) or ``--dark-w``, checked
    against the sweep's ports; None without either."""
    path, values = options["dark_file"], options["dark_w"]
    ports = len(sweep_table.port_names)
    expected = f"{sweep_table.source} has {ports} ports ({_port_list(sweep_table)})"
    if values is not None:
        if len(values) != ports:
            raise InputError(
                f"--dark-w gives {len(values)} value(s) but {expected}; give one offset per "
                "port, in that order",
                parameter="dark_w",
            )
        return np.array(values)
    if path is None:
        return None
    dark = read(
        path,
        request,
        need_x=False,
        drop_invalid=options["drop_invalid"],
        quiet=options["quiet"],
        light=False,
    ).valid_only()
    names = [port_key(name) for name in dark.port_names]
    if len(names) != ports or (
        request.ports is None and names != [port_key(name) for name in sweep_table.port_names]
    ):
        raise InputError(
            f"{dark.source} has ports {_port_list(dark)} but {expected}; the dark readings "
            "need the sweep's ports: pass --ports with the columns of both files in order"
        )
    if dark.n_rows == 0:
        raise InputError(f"{dark.source}: no valid dark readings to average")
    return dark.powers_w.mean(axis=0)


def _fit(options: dict, table, phases, dark_w):
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
        with _refused_if(options["strict"]):
            return calibrator.fit(
                table.powers_w,
                table.x_hz,
                table.monitor_w,
                list(table.port_names),
                dark_w=dark_w,
            )


def _metadata(table, dark_file) -> dict:
    """What the calibration was read from, kept in the calibration file (the dark readings'
    file only when there was one)."""
    temperature = table.temperature_k
    metadata = {
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
    if dark_file is not None:
        metadata["dark_file"] = STDIN_LABEL if is_stdio(dark_file) else str(dark_file)
    return metadata


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
@click.option(
    "--dark",
    "dark_file",
    metavar="FILE",
    type=click.Path(dir_okay=False),
    help="Readings with the source off, with the sweep's port columns (any supported format, "
    "no frequency column needed); their mean per port is subtracted from every reading.",
)
@click.option(
    "--dark-w",
    type=OFFSETS,
    metavar="W,W,..",
    help="Dark reading of each port, in port order: 1uW,-20nW,0 (signed; a bare number is "
    "in W); subtracted from every reading.",
)
@click.option(
    "--strict",
    is_flag=True,
    help="Treat calibration warnings as errors: write nothing and exit with code 3.",
)
@column_options()
@FORCE
@QUIET
def calibrate(sweep, out_path, port_phases_deg, force, **options):
    """Learn a calibration from a sweep of known frequencies.

    SWEEP is a CSV/TSV, HDF5, MAT, NPZ or Parquet file ('-' for stdin) with a frequency
    or wavelength column and three or more port columns. The calibration file must not
    exist unless --force is given; with -o - it goes to stdout and the summary to stderr.
    Calibration warnings print as 'warning: [cause] ...' lines on stderr (also with
    --quiet); with --strict they are errors (exit code 3) and nothing is written.

    \b
    Example:
      wavemeter calibrate sweep.csv -o chip.wmcal.json --fsr 50GHz
      wavemeter calibrate sweep.csv -o chip.wmcal.json --dark dark.csv --strict
      wavemeter calibrate lab.csv -o chip.wmcal.json --fsr '49.69 GHz' \\
          --x 'Wavelength (nm)' --ports 'Port 1 [dBm]','Port 2 [dBm]','Port 3 [dBm]'
    """
    from ..calibration.files import save_calibration

    dark_file = options["dark_file"]
    if dark_file is not None and options["dark_w"] is not None:
        raise InputError(
            "--dark and --dark-w both give the dark readings; give a file or values, not both"
        )
    if dark_file is not None and is_stdio(dark_file) and is_stdio(sweep):
        raise InputError("the sweep and --dark cannot both be read from stdin ('-')")
    check_calibration_output(out_path, (sweep, *([dark_file] if dark_file else [])), force)
    request = column_request(options)
    quiet = options["quiet"]
    table = read(
        sweep, request, need_x=True, drop_invalid=options["drop_invalid"], quiet=quiet
    ).valid_only()
    dark_w = _dark_w(options, request, table)
    calibration = _fit(options, table, port_phases_rad(port_phases_deg), dark_w)
    with output_path(out_path) as target:
        save_calibration(calibration, target, _metadata(table, dark_file))
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
