"""`wavemeter measure`: port readings to frequency with a calibration.

Every output row carries ``flags``, the calibration's quality bits for that reading
(:class:`wavemeter.calibration.flags.ReadingFlag`; a row skipped as invalid gets
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
"""

from __future__ import annotations

import warnings

import click
import numpy as np

from ..calibration.flags import ReadingFlag, flag_counts
from ..exceptions import CalibrationWarning, InputError
from ..io import write_table
from ..progress import busy, chunked
from ..units import SPEED_OF_LIGHT_M_S
from ._common import (
    FORCE,
    FORMAT,
    QUIET,
    about,
    check_ports,
    column_options,
    column_request,
    frequency_text,
    load,
    names,
    out_option,
    output_format,
    printable,
    read,
    say,
)
from ._params import OPTICAL_FREQUENCY, AliasedOption
from ._streams import is_stdio
from ._temperature import (
    check_temperature_options,
    needs_temperature,
    reading_temperature_k,
    temperature_k_option,
)

#: how to give the coarse frequencies, as the messages say it
COARSE_OPTIONS = "pass --coarse COL or --coarse-frequency VALUE"


def _coarse(calibration, cal_path, table, coarse_hz):
    """Coarse frequency per reading for a calibration that needs one (``"coarse_hz"`` in
    its ``requires``: a calibration set, a wide-band calibration); None for the others."""
    if "coarse_hz" not in calibration.requires:
        return None
    if table.coarse_hz is not None:
        return table.coarse_hz
    if coarse_hz is not None:
        return np.full(table.n_rows, coarse_hz)
    if hasattr(calibration, "windows_"):
        low, high = calibration.covered_hz()
        raise InputError(
            f"{cal_path} is a per-FSR calibration set ({len(calibration.windows_)} windows, "
            f"{low / 1e12:.6f} to {high / 1e12:.6f} THz): it needs a coarse frequency per "
            f"reading to pick the window; {COARSE_OPTIONS}"
        )
    low, high = calibration.span_hz_
    raise InputError(
        f"{cal_path} is a {calibration.method_label} calibration ({low / 1e12:.6f} to "
        f"{high / 1e12:.6f} THz, FSR {calibration.fsr_hz_ / 1e9:.6f} GHz): it needs a coarse "
        "frequency per reading, within half an FSR of the truth (e.g. the laser set point), "
        f"to pick the fringe order; {COARSE_OPTIONS}"
    )


#: cause of the warning that a cascade's readings are noisier than its calibration sweep
READING_NOISE_CAUSE = "reading_noise"


def _refuse_coarse(calibration, cal_path, coarse_column, coarse_hz) -> None:
    """A calibration that reads absolute frequency (a cascade) takes no coarse frequency."""
    if calibration.absolute_frequency and (coarse_column is not None or coarse_hz is not None):
        option = "--coarse" if coarse_column is not None else "--coarse-frequency"
        raise InputError(
            f"{cal_path} is a {calibration.method_label} calibration: its stages read the "
            f"absolute frequency and pick every fringe order themselves, so it has no use for a "
            f"coarse frequency; leave {option} out"
        )


def _noise_warning(calibration, noise_scale: np.ndarray) -> CalibrationWarning | None:
    """The warning that a cascade's readings are noisier than its calibration sweep, from
    the largest noise scale of each stage over the chunks (K,); None when none is."""
    noisier = np.flatnonzero(noise_scale > 1.0)
    if noisier.size == 0:
        return None
    fsrs = calibration.stage_fsrs_hz_
    stages = ", ".join(
        f"{noise_scale[index]:.3g}x in stage {index + 1} ({frequency_text(fsrs[index])})"
        for index in noisier
    )
    return CalibrationWarning(
        f"the readings are noisier than the calibration sweep: their detector noise is "
        f"{stages} the calibrated one (estimated from the readings' distances to each stage's "
        "model); frequency_std_hz and order_error_probability follow the readings' noise, "
        "and wrong orders grow more likely with it",
        cause=READING_NOISE_CAUSE,
        remedy="lower the readings' noise (more power, averaging) or recalibrate in the "
        "conditions of use",
    )


def flag_summary(flags: np.ndarray) -> str:
    """``flagged 12 of 1000 readings: OFF_MODEL 10, OUTSIDE_SPAN 2`` (a reading may have
    several bits, so the counts can add up to more than the readings flagged)."""
    counts = ", ".join(f"{name} {count}" for name, count in flag_counts(flags).items())
    text = f"flagged {int(np.count_nonzero(flags))} of {flags.size} readings"
    return f"{text}: {counts}" if counts else text


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("data", type=click.Path(dir_okay=False))
@out_option(
    "Output file: frequency_hz, wavelength_nm, phase_rad, frequency_std_hz, "
    "order_error_probability (cascade), flags per input row ('-': stdout)."
)
@click.option("--keep", metavar="COL,COL,..", help="Input columns to copy into the output.")
@FORMAT
@click.option(
    "--coarse",
    "coarse_column",
    metavar="COL",
    help="Coarse frequency or wavelength column, within half an FSR of the truth "
    "(calibration sets, wide-band calibrations).",
)
@click.option(
    "--coarse-frequency",
    "--coarse-hz",
    "coarse_hz",
    cls=AliasedOption,
    hidden_aliases=("--coarse-hz",),
    type=OPTICAL_FREQUENCY,
    help="One coarse frequency for every reading, 193.4THz or 1550nm; a bare number is in Hz "
    "(calibration sets, wide-band calibrations).",
)
@click.option(
    "--temperature",
    "temperature_column",
    metavar="COL",
    help="Temperature column in K or C, for a thermal calibration (default: found by name, "
    "e.g. temp_C).",
)
@temperature_k_option(
    "Chip temperature of every reading, for a thermal calibration, instead of a column: "
    "293.15 (K), 293.15K, 20C."
)
@click.option(
    "--uncertainty/--no-uncertainty",
    default=None,
    help="Write frequency_std_hz, each reading's standard deviation with the calibration's own "
    "uncertainty (default: when the calibration gives it, learned calibrations).",
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
    --drop-invalid are written as NaN with the INVALID flag.
    DATA '-' is read from stdin; with -o - the table goes to stdout (CSV unless --format)
    and messages to stderr. An existing output is replaced only with --force.

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
    """
    quiet = options["quiet"]
    file_format = output_format(
        out_path, file_format, inputs=(calibration_file, data), force=force
    )  # before any work
    calibration = load(calibration_file)
    _refuse_coarse(calibration, calibration_file, coarse_column, coarse_hz)
    offered = "frequency_std" in calibration.capabilities
    if uncertainty and not offered:
        raise InputError(
            f"{calibration_file}: --uncertainty needs a learned calibration (single or per "
            f"FSR), not a {calibration.method_label} calibration"
        )
    uncertainty = offered if uncertainty is None else uncertainty
    thermal = needs_temperature(calibration)
    column = options["temperature_column"]
    check_temperature_options(calibration, calibration_file, column=column, given=temperature_k)
    if column is not None and not thermal:
        raise InputError(
            f"--temperature names the chip temperature column for a calibration that needs "
            f"it (a thermal calibration); {calibration_file} is a "
            f"{calibration.method_label} calibration, which does not use it: leave "
            "--temperature out"
        )
    request = column_request(options, coarse=coarse_column, keep=names(keep) or ())
    table = read(
        data,
        request,
        need_x=False,
        drop_invalid=options["drop_invalid"],
        quiet=quiet,
        temperature=thermal and temperature_k is None,
    )
    check_ports(calibration, calibration_file, table, explicit=request.ports is not None)
    temperature = reading_temperature_k(calibration, calibration_file, table, temperature_k)
    valid = table.valid_only()
    coarse = _coarse(calibration, calibration_file, valid, coarse_hz)
    frequency = np.full(table.n_rows, np.nan)
    phase = np.full(table.n_rows, np.nan)
    std = np.full(table.n_rows, np.nan)
    flags = np.where(table.invalid, int(ReadingFlag.INVALID), 0)
    cascade = hasattr(calibration, "stages_")
    order_error = np.full(table.n_rows, np.nan) if cascade else None
    noise_scale = np.ones(len(calibration.stages_)) if cascade else None
    rows = np.flatnonzero(~table.invalid)
    description = printable(f"measuring {table.source}")
    for block in chunked(valid.n_rows, description, quiet=quiet):
        extra = {} if coarse is None else {"coarse_hz": coarse[block]}
        if temperature is not None:
            extra["temperature_k"] = temperature[rows[block]]
        with about(table.source):
            if cascade:  # every stage in one pass
                found = calibration.read(valid.powers_w[block])
                frequency[rows[block]] = found.frequency_hz[-1]
                phase[rows[block]] = found.phase_rad[-1]
                std[rows[block]] = found.std_hz[-1]
                order_error[rows[block]] = found.order_error_probability
                flags[rows[block]] = found.flags
                noise_scale = np.maximum(noise_scale, found.noise_scale)
                continue
            frequency[rows[block]] = calibration.predict(valid.powers_w[block], **extra)
            phase[rows[block]] = calibration.phase(valid.powers_w[block], **extra)
            if uncertainty:
                std[rows[block]] = calibration.frequency_std_hz(valid.powers_w[block], **extra)
            flags[rows[block]] = calibration.flags(valid.powers_w[block], **extra)
    if cascade and (noisier := _noise_warning(calibration, noise_scale)) is not None:
        warnings.warn(noisier, stacklevel=1)
    columns = {
        "frequency_hz": frequency,
        "wavelength_nm": SPEED_OF_LIGHT_M_S / frequency * 1e9,
        "phase_rad": phase,
        **({"frequency_std_hz": std} if uncertainty else {}),
        **({} if order_error is None else {"order_error_probability": order_error}),
        "flags": flags,
        **({} if temperature is None else {"temperature_k": temperature}),
    }
    for name, values in table.kept.items():
        columns.setdefault(name, values)
    with busy(printable(f"writing {out_path}"), quiet=quiet):
        write_table(out_path, columns, file_format)
    written = "stdout" if is_stdio(out_path) else out_path
    say(quiet, f"wrote {written} ({table.n_rows} rows)", err=is_stdio(out_path))
    say(quiet, flag_summary(flags), err=is_stdio(out_path))


command = measure
