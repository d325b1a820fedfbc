"""`wavemeter stream`: a live readout, one line of frequency per line of port readings.

Standard input (or ``--follow FILE``, a file being appended to) brings a header line, then
lines of port readings; each is turned into ``frequency_hz,wavelength_nm,frequency_std_hz,
flags`` (a cascade adds ``order_error_probability`` before ``flags``) and written to
standard output at once, flushed (:func:`wavemeter.jobs.stream_lines`). The columns are
found in the header as in files, with the same options as ``measure``. The end of the input
ends the command (exit code 0) with a one-line summary on stderr; Ctrl-C ends it the same
way with exit code 130, every line written so far complete; a reader that goes away (``|
head``) ends it quietly with exit code 0.
"""

from __future__ import annotations

import io
import os
import sys

import click

from ..jobs import check_readings, follow_lines, stream_lines
from ._common import QUIET, column_options, column_request, say
from ._readings import REMEDIES, checked_calibration, flag_summary, reading_input_options
from ._streams import STDIN_LABEL

#: exit code of a stream ended by Ctrl-C (128 + SIGINT), as a shell reports it
EXIT_INTERRUPTED = 130


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.option(
    "--follow",
    "follow_path",
    metavar="FILE",
    type=click.Path(dir_okay=False),
    help="Read FILE from its start, then every line appended to it (like tail -f), instead "
    "of standard input; stop with Ctrl-C.",
)
@reading_input_options
@column_options(axis=False, drop_invalid=False)
@QUIET
def stream(calibration_file, follow_path, coarse_column, coarse_hz, temperature_k, **options):
    """Live readout: turn lines of port readings into lines of frequency as they arrive.

    Reads a header line, then one reading per line (comma-, tab- or ;-separated, or as
    --delimiter says; an Excel sep= first line is understood) from standard input, or
    from FILE with --follow, and writes to standard output the line
    frequency_hz,wavelength_nm,frequency_std_hz,flags for each reading the moment it
    arrives (a cascade calibration adds order_error_probability before flags). Floats
    are written at full precision; frequency_std_hz is NaN for a calibration that gives
    none; flags are the quality bits of measure (1 OFF_MODEL, 2 OUTSIDE_SPAN,
    4 POWER_RANGE, 8 INVALID, 16 TEMPERATURE_RANGE, 32 ORDER_AMBIGUOUS). The columns are
    found in the header by name with their units, as in files (P1_mW, 'Port 3 [uW]',
    temp_C), or chosen with --ports, --power-unit, --temperature and --coarse. A line
    that holds no valid reading (cells missing, text, NaN, no light) is written as NaN
    with the INVALID flag and a warning line on stderr; blank lines and # comments are
    skipped.

    The end of the input ends the command with a summary line on stderr (unless --quiet);
    so does Ctrl-C, with exit code 130. A reader that stops reading (| head) ends it
    quietly.

    \b
    Example:
      logger | wavemeter stream chip.wmcal.json
      wavemeter stream chip.wmcal.json --follow readings.csv > frequencies.csv
      wavemeter stream thermal.wmcal.json --follow log.tsv --temperature 'Temp (C)'
      wavemeter stream band.wmcal.json --coarse-frequency 193.4THz < readings.csv
    """
    quiet = options["quiet"]
    calibration, _ = checked_calibration(
        calibration_file, coarse_column, coarse_hz, temperature_k, None, options
    )
    request = column_request(options, coarse=coarse_column)
    if follow_path is None:
        label = STDIN_LABEL
        lines = io.TextIOWrapper(sys.stdin.buffer, encoding="utf-8", errors="replace")
    else:
        label = follow_path
        lines = follow_lines(follow_path)

    def check(header) -> None:
        check_readings(
            calibration,
            header,
            coarse_hz=coarse_hz,
            temperature_k=temperature_k,
            ports_given=request.ports is not None,
            name=calibration_file,
            remedies={
                **REMEDIES,
                "temperature_k": "pass --temperature COL, or --temperature-k T for every reading",
            },
        )

    try:
        summary = stream_lines(
            calibration,
            lines,
            sys.stdout,
            request=request,
            coarse_hz=coarse_hz,
            temperature_k=temperature_k,
            name=label,
            check=check,
        )
    except BrokenPipeError:
        # the reader is gone: nothing more to write, and nothing to flush at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return
    ended = "stopped by Ctrl-C" if summary.interrupted else "end of input"
    say(
        quiet,
        f"{ended}: streamed {summary.rows} readings from {summary.source}, "
        f"{summary.invalid_rows} invalid; "
        + flag_summary(summary.flag_counts, summary.flagged, summary.rows),
        err=True,
    )
    if summary.interrupted:  # as SIGTERM ends a command (app.main): no "error:" line
        raise SystemExit(EXIT_INTERRUPTED)


command = stream
