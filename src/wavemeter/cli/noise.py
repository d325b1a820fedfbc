"""`wavemeter noise`: the frequency noise, linewidth and stability of a laser from readings.

The readings are measured with the calibration a chunk at a time
(:func:`wavemeter.jobs.noise.measure_series`: invalid and untrustworthy readings
excluded and counted, a single interferometer's readings unwrapped across its FSR, the
rate given or from a time column checked for uniform sampling), analysed whole
(:func:`wavemeter.analysis.frequency_noise`: PSD with the meter's floor, linewidths,
drift, Allan deviations), and written as an HTML page (:mod:`wavemeter.report.noise`)
and/or printed as JSON. ``-o`` is optional with ``--json``: the numbers alone.
"""

from __future__ import annotations

import contextlib
import json

import click

from ..atomic import check_output
from ..exceptions import InputError
from ..jobs.noise import measure_series
from ..progress import busy, progress_bar
from ._common import (
    FORCE,
    FREQUENCY,
    QUIET,
    about,
    column_options,
    column_request,
    note,
    printable,
    say,
)
from ._params import DURATION
from ._readings import checked_calibration, flag_summary, open_readings, reading_input_options
from ._streams import STDIN_LABEL, is_stdio

#: how to give the sampling rate, as the messages say it
RATE_OPTIONS = "pass --rate (e.g. --rate 10MHz) or --time-column COL (the readings' time stamps)"


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("readings", type=click.Path(dir_okay=False, allow_dash=True))
@click.option(
    "-o",
    "--out",
    "out_path",
    type=click.Path(dir_okay=False),
    help="HTML report to write (figures embedded); optional with --json.",
)
@click.option(
    "--rate",
    "rate_hz",
    type=FREQUENCY,
    help="Sampling rate of the readings: 10MHz, 250kHz; a bare number is in Hz.",
)
@click.option(
    "--time-column",
    metavar="COL",
    help="Column with each reading's time (unit from its name: time_s, t_ms, 'Time (us)'; "
    "else s); it must be uniform, and agree with --rate if both are given.",
)
@click.option(
    "--observation-time",
    "observation_time_s",
    type=DURATION,
    help="Observation time of the beta-line linewidth: 1ms, 0.1s; a bare number is in s "
    "(default: the longest the PSD measures, a twelfth to a sixth of the record; longer, "
    "up to the record, extrapolates the fitted power law, with a warning).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the analysis as JSON on stdout.")
@reading_input_options
@column_options(axis=False, drop_invalid=False)
@FORCE
@QUIET
def noise(
    calibration_file,
    readings,
    out_path,
    rate_hz,
    time_column,
    observation_time_s,
    as_json,
    coarse_column,
    coarse_hz,
    temperature_k,
    force,
    **options,
):
    """Frequency noise, linewidth and stability of a laser from the meter's readings.

    Measures READINGS (port readings at a uniform rate) with the calibration and writes
    an HTML report: the frequency against time, the one-sided frequency-noise PSD with
    its confidence band, the meter's own noise floor (from each reading's standard
    deviation) and the beta separation line, the floor-subtracted PSD, the Allan,
    modified Allan and Hadamard deviations with confidence bands, and a summary: white,
    flicker and random-walk FM levels, the Lorentzian linewidth (pi h0; an upper limit
    when the laser is not above the meter's floor), the beta-line linewidth, the drift,
    each with its uncertainty. --json prints the same numbers on stdout (-o is then
    optional).

    The rate is --rate, or comes from --time-column (checked for uniform sampling and
    gaps); give at least 100 readings. Invalid readings and those flagged OFF_MODEL or
    ORDER_AMBIGUOUS are excluded and counted; a single interferometer's readings are
    unwrapped across its FSR. Long files are read in chunks, with progress. An existing
    report is replaced only with --force.

    \b
    Example:
      wavemeter noise chip.wmcal.json laser.csv --rate 10MHz -o noise.html
      wavemeter noise chip.wmcal.json laser.csv --time-column time_s -o noise.html
      wavemeter noise chip.wmcal.json laser.csv --rate 1MHz --json --observation-time 1ms
    """
    quiet = options["quiet"]
    if out_path is None and not as_json:
        raise InputError("nothing to write: give -o FILE for the report, or --json, or both")
    if rate_hz is None and time_column is None:
        raise InputError(f"no sampling rate for {readings}: {RATE_OPTIONS}")
    if out_path is not None and is_stdio(out_path):
        raise InputError(
            "the report is an HTML page and is not written to stdout: give -o FILE, or --json "
            "to print the numbers"
        )
    if out_path is not None:
        check_output(out_path, inputs=(calibration_file, readings), force=force)
    calibration, _ = checked_calibration(
        calibration_file, coarse_column, coarse_hz, temperature_k, None, options
    )
    settings = {
        "rate_hz": rate_hz,
        "time_column": time_column,
        "coarse_column": coarse_column,
        "coarse_hz": coarse_hz,
        "temperature_k": temperature_k,
    }
    series = _measured(calibration, calibration_file, readings, settings, options)
    with busy(printable(f"analysing {series.rows} readings of {series.source}"), quiet=quiet):
        result = _analysed(series, readings, observation_time_s)
    if out_path is not None:
        from ..report.noise import write_noise_report

        with busy(printable(f"writing {out_path}"), quiet=quiet):
            write_noise_report(
                result,
                out_path,
                series=series,
                input_files={"calibration": calibration_file, "readings": readings},
                force=force,
            )
    if as_json:
        click.echo(json.dumps(result.to_dict(), indent=1))  # JSON: text escaped by json
    _print_summary(quiet or as_json, series, result, out_path)


@contextlib.contextmanager
def _time_column_named(time_column):
    """A reader's error about the time column (read as a kept column) names it as such."""
    try:
        yield
    except InputError as exc:
        if time_column is None or exc.parameter != "keep":
            raise
        raise InputError(
            str(exc).replace("(given as keep)", "(given as the time column)"),
            parameter="time_column",
        ) from exc


def _measured(calibration, cal_path, readings, settings, options):
    """The readings measured as one series (checks of the file against the calibration
    first, as ``measure`` makes them)."""
    quiet = options["quiet"]
    time_column = settings["time_column"]
    temperature_k = settings["temperature_k"]
    request = column_request(
        options, coarse=settings["coarse_column"], keep=(time_column,) if time_column else ()
    )
    with _time_column_named(time_column):
        stream = open_readings(
            calibration,
            cal_path,
            readings,
            request,
            coarse_hz=settings["coarse_hz"],
            temperature_k=temperature_k,
            allow_invalid=True,
        )

    def progress(description, total, unit):
        return progress_bar(printable(description), total, quiet=quiet, unit=unit)

    series = measure_series(
        calibration,
        stream,
        request=request,
        rate_hz=settings["rate_hz"],
        time_column=time_column,
        coarse_hz=settings["coarse_hz"],
        temperature_k=temperature_k,
        progress=progress,
    )
    if series.excluded:
        reasons = ", ".join(f"{name} {count}" for name, count in series.excluded_counts.items())
        first = (
            f", first invalid: {', '.join(series.invalid_examples[:3])}"
            if series.invalid_examples
            else ""
        )
        note(
            quiet,
            f"{series.source}: excluded {series.excluded} of {series.rows} readings "
            f"({reasons}){first}",
        )
    return series


def _analysed(series, readings, observation_time_s):
    """The noise analysis of a measured series; errors name the readings file."""
    from ..analysis.noise import frequency_noise

    with about(STDIN_LABEL if is_stdio(readings) else readings):
        return frequency_noise(
            series.frequency_hz,
            series.rate_hz,
            meter_std_hz=series.meter_std_hz,
            fsr_hz=series.fsr_hz,
            scale_rel_std=series.scale_rel_std,
            observation_time_s=observation_time_s,
        )


def _print_summary(quiet: bool, series, result, out_path) -> None:
    """The summary table's lines, the flags and what was written (stdout)."""
    from ..report.noise import summary_rows

    if quiet:
        return
    say(quiet, flag_summary(series.flag_counts, series.flagged, series.rows))
    rows = summary_rows(result)
    width = max(len(label) for label, _ in rows) + 2
    for label, value in rows:
        say(quiet, f"{label:<{width}}{value}")
    if out_path is not None:
        say(quiet, f"wrote {out_path}")


command = noise
