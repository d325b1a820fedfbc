"""What ``measure``, ``stream`` and ``noise`` check before any reading: the calibration, and
that the options give what it needs (a coarse frequency, a temperature) and nothing it
refuses; and the line that sums up the flags of the readings measured."""

from __future__ import annotations

import click

from ..calibration.contract.flags import flag_summary
from ..exceptions import InputError
from ..io import iter_readings
from ..io.streaming import CHUNK_ROWS
from ._common import check_ports, load
from ._params import OPTICAL_FREQUENCY, AliasedOption
from ._streams import STDIN_LABEL, is_stdio
from ._temperature import (
    check_temperature_options,
    missing_temperature,
    needs_temperature,
    temperature_k_option,
)

__all__ = [
    "COARSE_OPTIONS",
    "FILE_TEMPERATURE_REMEDY",
    "check_coarse",
    "check_source",
    "open_readings",
    "refuse_coarse",
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


def check_coarse(calibration, cal_path, stream, coarse_hz) -> None:
    """A calibration that needs a coarse frequency per reading (``"coarse_hz"`` in its
    ``requires``: a calibration set, a wide-band calibration) gets it from a column or
    --coarse-frequency."""
    if "coarse_hz" not in calibration.requires:
        return
    if stream.coarse_column is not None or coarse_hz is not None:
        return
    parts = calibration.parts()
    if parts:
        low = min(part.range_hz[0] for part in parts)
        high = max(part.range_hz[1] for part in parts)
        kind = parts[0].kind
        raise InputError(
            f"{cal_path} is a {calibration.method_label} calibration ({len(parts)} {kind}s, "
            f"{low / 1e12:.6f} to {high / 1e12:.6f} THz): it needs a coarse frequency per "
            f"reading to pick the {kind}; {COARSE_OPTIONS}"
        )
    low, high = calibration.span_hz_
    raise InputError(
        f"{cal_path} is a {calibration.method_label} calibration ({low / 1e12:.6f} to "
        f"{high / 1e12:.6f} THz, FSR {calibration.fsr_hz_ / 1e9:.6f} GHz): it needs a coarse "
        "frequency per reading, within half an FSR of the truth (e.g. the laser set point), "
        f"to pick the fringe order; {COARSE_OPTIONS}"
    )


def check_source(calibration, cal_path, source, coarse_hz, temperature_k, *, ports_given, remedy):
    """What the readings ``source`` (a stream or a header) offers fits the calibration: its
    ports, a temperature when it needs one (``remedy``: how to give it, for the message), a
    coarse frequency when it needs one."""
    check_ports(calibration, cal_path, source, explicit=ports_given)
    if needs_temperature(calibration) and temperature_k is None:
        if source.temperature_column is None:
            raise missing_temperature(
                f"{cal_path} is a {calibration.method_label} calibration: it",
                source.source,
                remedy,
            )
    check_coarse(calibration, cal_path, source, coarse_hz)


def open_readings(calibration, cal_path, data, request, *, coarse_hz, temperature_k, allow_invalid):
    """The readings file ``data`` (``-``: standard input) opened in chunks
    (:func:`~wavemeter.io.iter_readings`) and checked against the calibration
    (:func:`check_source`)."""
    stream = iter_readings(
        data,
        request,
        chunk_rows=CHUNK_ROWS,
        allow_invalid=allow_invalid,
        find_temperature=needs_temperature(calibration) and temperature_k is None,
        name=STDIN_LABEL if is_stdio(data) else str(data),
    )
    check_source(
        calibration,
        cal_path,
        stream,
        coarse_hz,
        temperature_k,
        ports_given=request.ports is not None,
        remedy=FILE_TEMPERATURE_REMEDY,
    )
    return stream


def refuse_coarse(calibration, cal_path, coarse_column, coarse_hz) -> None:
    """A calibration that reads absolute frequency (a cascade) takes no coarse frequency."""
    if calibration.absolute_frequency and (coarse_column is not None or coarse_hz is not None):
        option = "--coarse" if coarse_column is not None else "--coarse-frequency"
        raise InputError(
            f"{cal_path} is a {calibration.method_label} calibration: its stages read the "
            f"absolute frequency and pick every fringe order themselves, so it has no use for a "
            f"coarse frequency; leave {option} out"
        )


def checked_calibration(cal_path, coarse_column, coarse_hz, temperature_k, uncertainty, options):
    """The calibration and whether to write frequency_std_hz, after the checks of the
    options that need no readings."""
    calibration = load(cal_path)
    refuse_coarse(calibration, cal_path, coarse_column, coarse_hz)
    offered = "frequency_std" in calibration.capabilities
    if uncertainty and not offered:
        raise InputError(
            f"{cal_path}: --uncertainty needs a learned calibration (single or per "
            f"FSR), not a {calibration.method_label} calibration"
        )
    column = options["temperature_column"]
    check_temperature_options(calibration, cal_path, column=column, given=temperature_k)
    if column is not None and not needs_temperature(calibration):
        raise InputError(
            f"--temperature names the chip temperature column for a calibration that needs "
            f"it (a thermal calibration); {cal_path} is a "
            f"{calibration.method_label} calibration, which does not use it: leave "
            "--temperature out"
        )
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
