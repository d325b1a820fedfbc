"""`wavemeter measure`: port readings to frequency with a calibration.

Every output row carries ``flags``, the calibration's quality bits for that reading
(:class:`wavemeter.calibration.contract.flags.ReadingFlag`; a row skipped as invalid gets
``INVALID``), and ``frequency_std_hz`` where the calibration gives it. A calibration that
needs the chip temperature (``"temperature_k"`` in its ``requires``: a thermal one) gets it
from the readings' temperature column or ``--temperature-k`` for the whole file, and the
output has a ``temperature_k`` column: the temperature (K) each reading was retrieved at.
A calibration that needs a coarse frequency of each reading (``"coarse_hz"`` in its
``requires``: a per-FSR set, which picks the window by it, or a wide-band calibration,
which picks the fringe order) gets it from ``--coarse COL`` or ``--coarse-frequency``.

A cascade calibration reads absolute frequency with no coarse input (and refuses one): each
chunk of readings is read in one pass (:meth:`~wavemeter.CascadeCalibrator.read`), and the
output adds ``order_error_probability``, the probability that some stage picked a wrong
fringe order. When a stage's readings are noisier than its calibration sweep, one
``warning: [reading_noise]`` line says which and by how much: the uncertainties and order
probabilities written follow the readings' own noise.

The file is read, measured and written a chunk of rows at a time
(:func:`wavemeter.jobs.measure_file`), so the memory does not grow with the file; the output
appears only once complete. DATA may also be a folder or a quoted glob pattern: each data
file is measured into OUTDIR, and a file that fails is reported while the others go on.
"""

from __future__ import annotations

from pathlib import Path

import click

from ..atomic import check_output
from ..exceptions import InputError, WavemeterError
from ..io.formats import FILE_FORMATS
from ..jobs import ReadingsRefused, measure_file
from ..progress import progress_bar
from ._common import (
    FORCE,
    FORMAT,
    QUIET,
    column_options,
    column_request,
    error_text,
    names,
    note,
    one_line,
    output_format,
    printable,
    say,
)
from ._data_files import data_files, names_many_files
from ._readings import checked_calibration, flag_summary, open_readings, reading_input_options
from ._streams import is_stdio
from .app import Refused


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("data", type=click.Path())
@click.option(
    "-o",
    "--out",
    "out_path",
    required=True,
    type=click.Path(allow_dash=True),
    help="Output file: frequency_hz, wavelength_nm, phase_rad, frequency_std_hz, "
    "order_error_probability (cascade), flags per input row ('-': stdout); a folder "
    "when DATA is a folder or a glob pattern.",
)
@click.option("--keep", metavar="COL,COL,..", help="Input columns to copy into the output.")
@FORMAT
@reading_input_options
@click.option(
    "--uncertainty/--no-uncertainty",
    default=None,
    help="Write frequency_std_hz, each reading's standard deviation with the calibration's own "
    "uncertainty (default: when the calibration gives it, learned calibrations).",
)
@click.option(
    "--strict",
    is_flag=True,
    help="Refuse a file in which some reading cannot be read (a coarse value outside the "
    "calibrated range, no light, an invalid row...): exit code 3 and no output, instead of "
    "NaN and the flags that say why in those rows.",
)
@column_options(axis=False)
@FORCE
@QUIET
def measure(
    calibration_file,
    data,
    out_path,
    keep,
    file_format,
    coarse_column,
    coarse_hz,
    temperature_k,
    uncertainty,
    strict,
    force,
    **options,
):
    """Turn port readings into frequency with a calibration.

    Writes one row per input row, in order: frequency_hz, wavelength_nm (vacuum) and
    phase_rad at full float64 precision, frequency_std_hz (unless --no-uncertainty or
    the calibration gives none), flags (quality bits: 1 OFF_MODEL, 2 OUTSIDE_SPAN,
    4 POWER_RANGE, 8 INVALID, 16 TEMPERATURE_RANGE, 32 ORDER_AMBIGUOUS; 0 when nothing is
    wrong), for a thermal calibration temperature_k (the chip temperature used, K), then
    the --keep columns. A cascade calibration adds order_error_probability (unit-less,
    before flags): the probability that some stage picked a wrong fringe order, which flags
    ORDER_AMBIGUOUS above the calibration's --max-order-error. Rows skipped with
    --drop-invalid are written as NaN with the INVALID flag. A reading the calibration
    cannot read is written as NaN with the flags that say why, and costs no other reading;
    --strict refuses such a file instead (exit code 3, no output).
    DATA '-' is read from stdin; with -o - the table goes to stdout (CSV unless --format)
    and messages to stderr. An existing output is replaced only with --force. The file
    is read, measured and written in chunks: the memory does not grow with the file, and
    the output appears only once complete.

    DATA may be a folder (its data files) or a quoted glob pattern ('runs/*.h5'): each
    file is measured into the folder -o OUTDIR as <name>.<format extension> (CSV unless
    --format); a file that fails is reported with its error and the others go on, and
    the exit code is 2 when any failed.

    A thermal calibration needs the chip temperature of each reading: from a temperature
    column (found by name with its unit, e.g. temperature_K or 'Temp (C)', or
    --temperature COL) or --temperature-k for the whole file. A per-FSR calibration set
    and a wide-band calibration need a coarse frequency of each reading within half an
    FSR of the truth (--coarse COL, or --coarse-frequency for the whole file): it picks
    the window, or the fringe order. A cascade calibration needs none (and refuses one);
    when a stage's readings are noisier than its calibration sweep, a warning line says
    so, and the uncertainties and order probabilities follow the readings' noise.

    \b
    Example:
      wavemeter measure chip.wmcal.json readings.csv -o frequencies.csv --keep time_s
      wavemeter measure thermal.wmcal.json readings.csv -o f.csv --temperature 'Temp (C)'
      wavemeter measure band.wmcal.json readings.csv -o f.csv --coarse set_point_THz
      wavemeter measure cascade.wmcal.json readings.csv -o f.csv
      wavemeter measure chip.wmcal.json 'runs/*.parquet' -o measured/ --format parquet
    """
    quiet = options["quiet"]
    calibration_check = (calibration_file, coarse_column, coarse_hz, temperature_k, uncertainty)
    settings = {
        "keep": names(keep) or (),
        "coarse_column": coarse_column,
        "coarse_hz": coarse_hz,
        "temperature_k": temperature_k,
        "uncertainty": uncertainty,
        "errors": "raise" if strict else "coerce",
        "options": options,
    }
    if names_many_files(data):
        _measure_many(calibration_file, data, out_path, file_format, force, settings)
        return
    file_format = output_format(
        out_path, file_format, inputs=(calibration_file, data), force=force
    )  # before any work
    calibration, settings["uncertainty"] = checked_calibration(*calibration_check, options)
    try:
        summary = _measure_one(calibration, calibration_file, data, out_path, file_format, settings)
    except ReadingsRefused as exc:
        raise Refused(str(exc)) from None
    err = is_stdio(out_path)
    written = "stdout" if err else out_path
    say(quiet, f"wrote {written} ({summary.rows} rows)", err=err)
    say(quiet, flag_summary(summary.flag_counts, summary.flagged, summary.rows), err=err)


def _measure_one(calibration, cal_path, data, out_path, file_format, settings, *, bar=True):
    """Measure one file into ``out_path``; the summary. ``bar``: show its progress."""
    options = settings["options"]
    quiet = options["quiet"]
    request = column_request(options, coarse=settings["coarse_column"], keep=settings["keep"])
    stream = open_readings(
        calibration,
        cal_path,
        data,
        request,
        coarse_hz=settings["coarse_hz"],
        temperature_k=settings["temperature_k"],
        allow_invalid=options["drop_invalid"],
    )

    def progress(description, total, unit):
        return progress_bar(printable(description), total, quiet=quiet or not bar, unit=unit)

    summary = measure_file(
        calibration,
        stream,
        out_path,
        request=request,
        file_format=file_format,
        coarse_hz=settings["coarse_hz"],
        temperature_k=settings["temperature_k"],
        uncertainty=settings["uncertainty"],
        errors=settings["errors"],
        progress=progress,
    )
    if summary.invalid_rows:
        note(
            quiet,
            f"{summary.source}: skipped {summary.invalid_rows} invalid row(s), first: "
            f"{', '.join(summary.invalid_examples[:3])}",
        )
    return summary


def _output_paths(files: list[Path], out_dir, file_format, cal_path, force) -> list[Path]:
    """One output in ``out_dir`` per data file, ``<stem>.<ext of the format>``; all
    checked before any work (two inputs may not share an output, an existing output
    needs --force)."""
    if is_stdio(out_dir):
        raise InputError("many data files are measured into a folder: give -o OUTDIR, not -")
    folder = Path(out_dir)
    if folder.exists() and not folder.is_dir():
        raise InputError(
            f"{folder} is a file: many data files are measured into a folder; give -o OUTDIR"
        )
    if not folder.parent.is_dir():
        raise InputError(f"cannot write to {folder}: folder {folder.parent} does not exist")
    extension = FILE_FORMATS[[f.name for f in FILE_FORMATS].index(file_format)].extensions[0]
    outputs = [folder / f"{path.stem}{extension}" for path in files]
    seen: dict[Path, Path] = {}
    for path, output in zip(files, outputs, strict=True):
        if output in seen:
            raise InputError(
                f"{seen[output]} and {path} would both be measured into {output}: rename one, "
                "or measure them separately"
            )
        seen[output] = path
        if folder.is_dir():
            check_output(output, inputs=(cal_path, path), force=force)
    return outputs


def _measure_many(cal_path, data, out_dir, file_format, force, settings) -> None:
    """Measure every data file DATA names into ``out_dir``; a file that fails is reported
    (``error:``) and the others go on; exit code 2 at the end when any failed."""
    quiet = settings["options"]["quiet"]
    files = data_files(data)
    outputs = _output_paths(files, out_dir, file_format or "csv", cal_path, force)
    calibration, uncertainty = checked_calibration(
        cal_path,
        settings["coarse_column"],
        settings["coarse_hz"],
        settings["temperature_k"],
        settings["uncertainty"],
        settings["options"],
    )
    settings = {**settings, "uncertainty": uncertainty}
    Path(out_dir).mkdir(exist_ok=True)
    failed = refused = 0
    description = printable(f"measuring {len(files)} files into {out_dir}")
    with progress_bar(description, len(files), quiet=quiet, unit="files") as advance:
        for path, output in zip(files, outputs, strict=True):
            try:
                summary = _measure_one(
                    calibration, cal_path, path, output, file_format or "csv", settings, bar=False
                )
            except (WavemeterError, OSError) as exc:  # one error line, as main() prints it
                if isinstance(exc, ReadingsRefused):
                    refused += 1
                else:
                    failed += 1
                click.echo(one_line("error: ", error_text(exc)), err=True)
            else:
                say(quiet, f"wrote {output} ({summary.rows} rows)")
                say(quiet, flag_summary(summary.flag_counts, summary.flagged, summary.rows))
            advance(1)
    say(quiet, f"measured {len(files) - failed - refused} of {len(files)} files into {out_dir}")
    if failed:  # the command's own error line, exit code 2
        raise InputError(f"{failed + refused} of {len(files)} files failed (see above)")
    if refused:  # --strict: exit code 3
        raise Refused(f"--strict refused {refused} of {len(files)} files (see above)")


command = measure
