"""`wavemeter calibrate`: learn a calibration from a sweep file (several for a thermal one).

The command parses its options into :class:`wavemeter.jobs.CalibrateOptions`
(:mod:`wavemeter.cli._methods`), runs :func:`wavemeter.jobs.calibrate_file` (the job
``fleet calibrate`` runs for every device: reading, dark readings, fitting, metadata,
saving) and prints what was read, the fit's warnings and its summary. With ``--strict`` a
calibration warning of the fit is an error: nothing is written and the exit code is 3.
"""

from __future__ import annotations

import warnings

import click

from ..progress import busy, progress_bar
from ._common import (
    FORCE,
    QUIET,
    check_calibration_output,
    column_options,
    column_request,
    note,
    out_option,
    printable,
    say,
)
from ._methods import calibrate_options, method_options
from ._params import OFFSETS
from ._streams import is_stdio, output_path
from ._temperature import temperature_k_option
from .app import WarningsRefused


def progress(quiet: bool):
    """The jobs' ``progress(description, total, unit)``: a bar, or a spinner without a
    total; nothing with ``quiet``."""

    def show(description, total, unit):
        if total is None:
            return busy(printable(description), quiet=quiet)
        return progress_bar(printable(description), total, quiet=quiet, unit=unit)

    return show


def notes(quiet: bool, read) -> None:
    """``note:`` lines for the rows the job skipped as invalid, file by file."""
    records = [*read.records, *([read.dark] if read.dark is not None else [])]
    for record in records:
        if record.dropped_rows:
            note(
                quiet,
                f"{record.source}: skipped {record.dropped_rows} invalid row(s), first: "
                f"{', '.join(record.invalid_examples[:3])}",
            )


def read_line(read) -> str:
    """What was read: files, rows, axis, ports, monitor and temperature."""
    first = read.first
    rows = f"{read.n_rows} rows"
    if len(read.records) > 1:
        rows += f" ({' + '.join(str(record.n_rows) for record in read.records)})"
    text = (
        f"calibrated {read.label}: {rows}, axis {first.x_column} ({first.x_unit}), "
        f"ports {', '.join(first.port_names)}"
    )
    if first.monitor_column:
        text += f", monitor {first.monitor_column}"
    if read.temperature_from is not None:
        low, high = read.temperature_range_k
        source = "--temperature-k" if read.given_k else f"column {read.temperature_from}"
        text += f", temperature {low:.6g} to {high:.6g} K ({source})"
    return text


@click.command()
@click.argument(
    "sweeps", metavar="SWEEP [SWEEP ...]", nargs=-1, required=True, type=click.Path(dir_okay=False)
)
@out_option("Calibration file to write: JSON, e.g. chip.wmcal.json ('-' for stdout).")
@method_options
@temperature_k_option(
    "Chip temperature of every reading of a sweep file (thermal method), once per file in "
    "file order: 293.15 (K), 293.15K, 20C. Default: each file's temperature column.",
    multiple=True,
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
def calibrate(sweeps, out_path, force, **options):
    """Learn a calibration from a sweep of known frequencies.

    SWEEP is a CSV/TSV, HDF5, MAT, NPZ or Parquet file ('-' for stdin) with a frequency
    or wavelength column and three or more port columns. The calibration file must not
    exist unless --force is given; with -o - it goes to stdout and the summary to stderr.
    Calibration warnings print as 'warning: [cause] ...' lines on stderr (also with
    --quiet); with --strict they are errors (exit code 3) and nothing is written.

    --method takes the methods of the registry, built in and of installed plug-ins. The
    method-specific options (--fsr-tolerance, --retrieval, --phase-order, --map-order,
    --stage-ports, --max-order-error, --temperature-std-k, --port-phases-deg) are settings
    of the method's calibrator: left out, the method's default; given to a method without
    that setting, an error naming the methods that have it.

    --method thermal takes one or more sweeps (at two or more temperatures, or one
    recording while the temperature changes), concatenated in the order given, with the
    chip temperature of every reading from a temperature column (found by name with its
    unit, e.g. temperature_K or 'Temp (C)', or --temperature COL) or --temperature-k once
    per file. The other methods take one sweep.

    --method wideband fits one model across a sweep of many FSRs (whole FSRs may be
    missing): a phase polynomial of order --phase-order and a map of Legendre order
    --map-order in frequency, both chosen by cross-validation on held-out FSRs unless
    given. Measuring with it needs a coarse frequency of each reading within half an
    FSR (--coarse or --coarse-frequency), which picks the fringe order.

    --method cascade calibrates stages of decreasing FSR (--fsr 5THz,500GHz,50GHz,
    coarsest first; the coarsest must exceed the band) from one sweep over the band: the
    port columns read, in order, are the stages' columns, in consecutive blocks of equal
    size or as --stage-ports says. Each stage picks the fringe order of the next, so
    readings need no coarse frequency; a hand-over the sweep's noise makes unreliable
    (wrong-order rate above --max-order-error) is refused with the largest FSR ratio the
    noise allows.

    A method that can fit a sweep in chunks (the "fit_chunks" capability: learned, not
    --per-fsr) reads it in chunks, with a progress bar, in memory bounded by the chunk:
    files larger than memory work. Beyond 2^17 readings it is fitted on sums over every
    reading and its checks and diagnostics see every k-th reading (the summary says how
    many). The other methods and --per-fsr read the whole sweep into memory.

    \b
    Example:
      wavemeter calibrate sweep.csv -o chip.wmcal.json --fsr 50GHz
      wavemeter calibrate sweep.csv -o chip.wmcal.json --dark dark.csv --strict
      wavemeter calibrate lab.csv -o chip.wmcal.json --fsr '49.69 GHz' \\
          --x 'Wavelength (nm)' --ports 'Port 1 [dBm]','Port 2 [dBm]','Port 3 [dBm]'
      wavemeter calibrate --method thermal cold.csv mid.csv warm.csv -o chip.wmcal.json
      wavemeter calibrate --method thermal a.csv b.csv --temperature-k 20C \\
          --temperature-k 21.5C -o chip.wmcal.json
      wavemeter calibrate --method wideband band.csv -o band.wmcal.json --phase-order 2
      wavemeter calibrate --method cascade cband.csv -o cascade.wmcal.json \\
          --fsr 5THz,500GHz,50GHz --stage-ports 1-3/4-6/7-9
    """
    from ..jobs import CalibrationRefused, calibrate_file

    quiet = options["quiet"]
    dark_w = options["dark_w"]
    job, check = calibrate_options(
        options,
        request=column_request(options),
        drop_invalid=options["drop_invalid"],
        dark_w=None if dark_w is None else tuple(dark_w),
        dark_file=options["dark_file"],
        temperature_k=tuple(options["temperature_k"]),
        strict=options["strict"],
    )
    inputs = (*sweeps, *([job.dark_file] if job.dark_file else []))
    check_calibration_output(out_path, inputs, force)
    try:
        with output_path(out_path) as target:
            result = calibrate_file(
                sweeps, target, options=job, progress=progress(quiet), check=check
            )
    except CalibrationRefused as exc:
        raise WarningsRefused(exc.warnings, "--strict: no calibration written") from None
    notes(quiet, result.read)
    for warning in result.fit_warnings:  # one "warning:" line each (app.main)
        warnings.warn(warning, stacklevel=1)
    to_stderr = is_stdio(out_path)
    say(quiet, read_line(result.read), err=to_stderr)
    say(quiet, result.calibration.summary().text, err=to_stderr)
    say(quiet, f"wrote {'the calibration to stdout' if to_stderr else out_path}", err=to_stderr)


command = calibrate
