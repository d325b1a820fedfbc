"""What ``measure``, ``stream`` and ``noise`` share: the options of a calibration's
per-reading inputs, the checks of the readings against the calibration (those of
:mod:`wavemeter.jobs.readings`, with remedies that name the options), and the line that
sums up the flags of the readings measured."""

from __future__ import annotations

import click

from ..calibration.contract.flags import flag_summary
from ..io import iter_readings
from ..io.streaming import CHUNK_ROWS
from ..jobs.readings import check_reading_options, check_readings, needs_temperature
from ._common import load
from ._params import OPTICAL_FREQUENCY, AliasedOption
from ._streams import STDIN_LABEL, is_stdio
from ._temperature import temperature_k_option

__all__ = [
    "COARSE_OPTIONS",
    "FILE_TEMPERATURE_REMEDY",
    "REMEDIES",
    "open_readings",
    "checked_calibration",
    "flag_summary",
    "reading_input_options",
]

#: how to give the chip temperature of a file's readings, as the messages say it
FILE_TEMPERATURE_REMEDY = (
    "pass --temperature COL, or --temperature-k T for one temperature for the file"
)
#: how to give the coarse frequencies, as the messages say it
COARSE_OPTIONS = "pass --coarse COL or --coarse-frequency VALUE"
#: how to give what the readings lack, by library parameter (jobs.readings)
REMEDIES = {
    "ports": "pass --ports with the file's columns in the calibration's order",
    "temperature_k": FILE_TEMPERATURE_REMEDY,
    "coarse_hz": COARSE_OPTIONS,
}


def open_readings(calibration, cal_path, data, request, *, coarse_hz, temperature_k, allow_invalid):
    """The readings file ``data`` (``-``: standard input) opened in chunks
    (:func:`~wavemeter.io.iter_readings`) and checked against the calibration
    (:func:`wavemeter.jobs.check_readings`, its remedies naming the options)."""
    stream = iter_readings(
        data,
        request,
        chunk_rows=CHUNK_ROWS,
        allow_invalid=allow_invalid,
        find_temperature=needs_temperature(calibration) and temperature_k is None,
        name=STDIN_LABEL if is_stdio(data) else str(data),
    )
    check_readings(
        calibration,
        stream,
        coarse_hz=coarse_hz,
        temperature_k=temperature_k,
        ports_given=request.ports is not None,
        name=cal_path,
        remedies=REMEDIES,
    )
    return stream


def checked_calibration(cal_path, coarse_column, coarse_hz, temperature_k, uncertainty, options):
    """The calibration and whether to write frequency_std_hz, after the checks of the
    options that need no readings (:func:`wavemeter.jobs.check_reading_options`)."""
    calibration = load(cal_path)
    check_reading_options(
        calibration,
        name=cal_path,
        coarse_column=coarse_column,
        coarse_hz=coarse_hz,
        temperature_column=options["temperature_column"],
        temperature_k=temperature_k,
        uncertainty=uncertainty,
    )
    offered = "frequency_std" in calibration.capabilities
    return calibration, offered if uncertainty is None else uncertainty


def reading_input_options(command):
    """The options that give a calibration its per-reading inputs (``measure``, ``stream``):
    --coarse, --coarse-frequency, --temperature, --temperature-k."""
    for option in reversed(
        [
            click.option(
                "--coarse",
                "coarse_column",
                metavar="COL",
                help="Coarse frequency or wavelength column, within half an FSR of the truth "
                "(calibration sets, wide-band calibrations).",
            ),
            click.option(
                "--coarse-frequency",
                "--coarse-hz",
                "coarse_hz",
                cls=AliasedOption,
                hidden_aliases=("--coarse-hz",),
                type=OPTICAL_FREQUENCY,
                help="One coarse frequency for every reading, 193.4THz or 1550nm; a bare number "
                "is in Hz (calibration sets, wide-band calibrations).",
            ),
            click.option(
                "--temperature",
                "temperature_column",
                metavar="COL",
                help="Temperature column in K or C, for a thermal calibration (default: found by "
                "name, e.g. temp_C).",
            ),
            temperature_k_option(
                "Chip temperature of every reading, for a thermal calibration, instead of a "
                "column: 293.15 (K), 293.15K, 20C."
            ),
        ]
    ):
        command = option(command)
    return command
