"""What the commands share: option decorators, parameter types, reading, writing, messages."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import unicodedata
from pathlib import Path

import click
import numpy as np

from ..atomic import check_output
from ..exceptions import InputError, WavemeterError
from ..io import FORMATS, ColumnRequest, read_table, table_format
from ..io.convert import NO_LIGHT_REASON
from ..progress import busy
from ..units import SPEED_OF_LIGHT_M_S, frequency_text
from ._params import DELIMITER, FREQUENCY, FSR, AliasedOption, FrequencyParam
from ._streams import STDIN_LABEL, is_stdio

__all__ = [
    "one_line",
    "error_text",
    "FREQUENCY",
    "FSR",
    "FrequencyParam",
    "QUIET",
    "FORMAT",
    "FORCE",
    "PORT_PHASES",
    "printable",
    "say",
    "note",
    "about",
    "names",
    "port_phases_rad",
    "setting",
    "out_option",
    "column_options",
    "column_request",
    "output_format",
    "read",
    "load",
    "check_ports",
    "fsr_text",
    "frequency_text",
    "optical_text",
    "noise_text",
]

#: Unicode categories never printed: controls (C0, C1, DEL), format characters (bidi
#: overrides, zero-width marks) and lone surrogates
_UNPRINTED_CATEGORIES = ("Cc", "Cf", "Cs")


def printable(text) -> str:
    """``str(text)`` with control characters (ESC, other C0/C1, DEL), bidi overrides and other
    format characters replaced by ``?``; tab and newline are kept.

    Everything the command line prints that may come from a file or the user (names,
    values, error messages) goes through this, so a file cannot drive the terminal; the
    ``?`` shows that something was there rather than hiding it.
    """
    return "".join(
        char if char in "\n\t" or unicodedata.category(char) not in _UNPRINTED_CATEGORIES else "?"
        for char in str(text)
    )


def one_line(prefix: str, text) -> str:
    """``prefix`` and ``text`` on one line, without control characters: how every
    ``error:`` and ``warning:`` line is printed."""
    return prefix + " ".join(printable(text).split())


def names(text: str | None) -> tuple[str, ...] | None:
    """Comma-separated column names, or None."""
    if text is None:
        return None
    names = tuple(name.strip() for name in text.split(","))
    if not all(names):
        raise InputError(f"empty column name in {text!r}; separate names with single commas")
    return names


def port_phases_rad(text: str | None) -> np.ndarray | None:
    if text is None:
        return None
    try:
        return np.deg2rad([float(value) for value in text.split(",")])
    except ValueError as exc:
        raise InputError(
            f"--port-phases-deg must be numbers separated by commas, got {text!r}"
        ) from exc


def say(quiet: bool, text: str, *, err: bool = False) -> None:
    """Print a result line (stdout, or stderr with ``err``) unless ``quiet``."""
    if not quiet:
        click.echo(printable(text), err=err)


def note(quiet: bool, text: str) -> None:
    """Print ``note: text`` on stderr unless ``quiet``."""
    if not quiet:
        click.echo(f"note: {printable(text)}", err=True)


def _renamed(exc: WavemeterError, text: str) -> WavemeterError:
    """An error of the same type and parameter with another message."""
    renamed = type(exc)(text)
    renamed.parameter = getattr(exc, "parameter", None)
    return renamed


@contextlib.contextmanager
def about(path):
    """Prefix an error raised by the library with the file it concerns."""
    try:
        yield
    except WavemeterError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise _renamed(exc, f"{path}: {exc}") from exc


@contextlib.contextmanager
def _stdin_named(path):
    """Errors about stdin (``-``) name it ``<stdin>``."""
    try:
        yield
    except WavemeterError as exc:
        prefix = f"{path}: "
        if not is_stdio(path) or not str(exc).startswith(prefix):
            raise
        raise _renamed(exc, f"{STDIN_LABEL}: {str(exc)[len(prefix) :]}") from exc


def fsr_text(fsr_hz: float) -> str:
    """An FSR as every command prints it: ``49.584877 GHz``."""
    return f"{fsr_hz / 1e9:.6f} GHz"


def optical_text(frequency_hz: float) -> str:
    """An optical frequency as every command prints it: ``193.399988 THz (1550.1162 nm)``."""
    return f"{frequency_hz / 1e12:.6f} THz ({SPEED_OF_LIGHT_M_S / frequency_hz * 1e9:.4f} nm)"


def noise_text(noise_w: float) -> str:
    """A detector noise standard deviation as every command prints it: ``5.012e-07 W``."""
    return f"{noise_w:.4g} W"


#: width of the label column of the lines ``info`` and ``calibrate`` print
LABEL_WIDTH = 17


def _finite(value) -> float | None:
    """A finite number of a calibration file, else None (a file may be hand-edited)."""
    is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
    return float(value) if is_number and math.isfinite(value) else None


# ---------------------------------------------------------------------------- shared options
QUIET = click.option("--quiet", is_flag=True, help="Print nothing but errors.")
FORMAT = click.option(
    "--format",
    "file_format",
    type=click.Choice(FORMATS),
    help="File format (default: from the extension; CSV for '-', stdout).",
)
PORT_PHASES = click.option(
    "--port-phases-deg",
    metavar="DEG,DEG,..",
    help="Nominal port phases (deg) for the conventional method (default 360 j / n).",
)
FORCE = click.option("--force", is_flag=True, help="Replace an existing output file.")


def setting(name: str, default, kind, help_text: str, *, dest=None, aliases=(), metavar=None):
    """An option with a default, shown in ``--help``; ``aliases`` are old names that still
    work but are not shown."""
    declarations = [name, *aliases, *([dest] if dest else [])]
    return click.option(
        *declarations,
        cls=AliasedOption,
        hidden_aliases=aliases,
        default=default,
        show_default=True,
        type=kind,
        metavar=metavar,
        help=help_text,
    )


def out_option(help_text: str):
    """The required ``-o/--out`` file option (``-`` is stdout)."""
    return click.option(
        "-o",
        "--out",
        "out_path",
        required=True,
        type=click.Path(dir_okay=False, allow_dash=True),
        help=help_text,
    )


def column_options(*, axis: bool = True, drop_invalid: bool = True):
    """Options that choose columns and units of an input file (see DESIGN, input files)
    and how a text input's cells are written (--delimiter, --decimal); ``axis``: the
    frequency axis, monitor and temperature columns; ``drop_invalid``: the --drop-invalid
    switch (a stream always writes invalid rows as NaN)."""

    def decorate(command):
        options = [
            click.option(
                "--ports",
                "ports_columns",
                metavar="COL,COL,..",
                help="Port columns in order (default: found by name, e.g. P1_mW, 'DC CH1').",
            ),
            click.option(
                "--power-unit",
                metavar="UNIT",
                help="Unit of the port columns: W, mW, uW, nW, dBm or V (default: from names).",
            ),
            click.option(
                "--delimiter",
                type=DELIMITER,
                help="Column delimiter of CSV/TSV input: one character (, ; |), tab or space "
                "(default: an Excel sep= first line's, else found from the file).",
            ),
            click.option(
                "--decimal",
                type=click.Choice([".", ","]),
                help="Decimal mark of CSV/TSV input (default: '.', or ',' for a ';'-separated "
                "file written with decimal commas, with a note).",
            ),
        ]
        if drop_invalid:
            options.append(
                click.option(
                    "--drop-invalid",
                    is_flag=True,
                    help="Skip rows with NaN, power-meter sentinels or no light instead of "
                    "failing.",
                )
            )
        if axis:
            options += [
                click.option(
                    "--x",
                    "x_column",
                    metavar="COL",
                    help="Frequency or wavelength column (default: found by name).",
                ),
                click.option(
                    "--x-unit",
                    metavar="UNIT",
                    help="Unit of --x: Hz, kHz, MHz, GHz, THz, nm, um or m (default: from name).",
                ),
                click.option(
                    "--monitor",
                    "monitor_column",
                    metavar="COL",
                    help="Source-power monitor column (default: found by name, e.g. monitor_mW).",
                ),
                click.option(
                    "--temperature",
                    "temperature_column",
                    metavar="COL",
                    help="Temperature column in K or C (default: found by name, e.g. temp_C).",
                ),
            ]
        for option in reversed(options):
            command = option(command)
        return command

    return decorate


def column_request(options: dict, **extra) -> ColumnRequest:
    return ColumnRequest(
        x=options.get("x_column"),
        x_unit=options.get("x_unit"),
        ports=names(options.get("ports_columns")),
        power_unit=options.get("power_unit"),
        monitor=options.get("monitor_column"),
        temperature=options.get("temperature_column"),
        delimiter=options.get("delimiter"),
        decimal=options.get("decimal"),
        **extra,
    )


def _light_not_needed(table):
    """The table with rows whose only problem is no light made valid (dark readings)."""
    no_light = [k for k, reason in enumerate(table.invalid_reasons) if reason == NO_LIGHT_REASON]
    dark_rows = np.isin(table.invalid_code, no_light)
    return dataclasses.replace(table, invalid_code=np.where(dark_rows, -1, table.invalid_code))


def read(
    path,
    request: ColumnRequest,
    *,
    need_x: bool,
    drop_invalid: bool,
    quiet: bool,
    light: bool = True,
    temperature: bool | None = None,
):
    """Read a data file (``-``: stdin); with ``drop_invalid`` skip bad rows and say how many.

    Files with known frequencies (``need_x``: sweeps, test files) also get their power
    monitor and temperature columns; readings to measure need neither. ``temperature``
    (default ``need_x``) says whether to look for a temperature column by name: readings
    for a calibration that needs the chip temperature get it, a sweep whose temperature is
    given another way does not. Dark readings
    (``light=False``, the source off) may sum to zero or less: only NaN, sentinels and
    implausible values make their rows invalid. The table's ``source`` is the name the
    user gave (``<stdin>`` for ``-``)."""
    label = STDIN_LABEL if is_stdio(path) else path
    with busy(printable(f"reading {label}"), quiet=quiet), _stdin_named(path):
        table = read_table(
            path,
            request,
            need_x=need_x,
            find_extras=need_x,
            allow_invalid=drop_invalid or not light,
            find_temperature=temperature,
        )
    if is_stdio(path):
        table = dataclasses.replace(table, source=Path(STDIN_LABEL))
    if not light:
        table = _light_not_needed(table)
        if table.invalid.any() and not drop_invalid:
            raise InputError(
                f"{table.source}: {int(table.invalid.sum())} invalid row(s): "
                f"{table.describe_invalid()}; fix or delete them, or allow invalid rows to "
                "skip them (allow_invalid)",
                parameter="allow_invalid",
            )
    if table.invalid.any():
        note(
            quiet,
            f"{table.source}: skipped {int(table.invalid.sum())} invalid row(s), first: "
            f"{table.describe_invalid(3)}",
        )
    return table


def read_calibration(path):
    """A calibration file's content, calibrator and metadata (not from stdin: a calibration
    is small and named)."""
    from ..calibration.files.document import read_calibration_file

    if is_stdio(path):
        raise InputError("a calibration is read from its file, not from stdin ('-')")
    return read_calibration_file(path)


def load(path):
    """A calibration from its file (see :func:`read_calibration`)."""
    return read_calibration(path).calibrator


def check_calibration_output(out_path, inputs, force: bool) -> None:
    """Before any work: the output is not an input, may be replaced, and is JSON."""
    check_output(out_path, inputs=inputs, force=force)
    if not is_stdio(out_path) and Path(out_path).suffix.lower() != ".json":
        raise InputError(
            f"cannot write {out_path}: a calibration file is JSON; give a name ending in "
            ".json (e.g. chip.wmcal.json), or - for stdout"
        )


def output_format(path, file_format: str | None, *, inputs=(), force: bool = False) -> str:
    """Check a table output before any work and return the format to write it in.

    The output must not be an input, must be a regular file (or ``-``, stdout) and may
    replace an existing file only with ``force``; its extension must be one the writer
    knows unless ``file_format`` is given.
    """
    check_output(path, inputs=inputs, force=force)
    return table_format(path, file_format)


def check_ports(calibration, cal_path, table, explicit: bool) -> None:
    """The file's ports must be the calibration's: same count and, unless chosen with
    --ports, the same names (units aside) (:func:`wavemeter.jobs.check_ports`)."""
    from ..jobs.readings import check_ports as check

    hint = "pass --ports with the file's columns in the calibration's order"
    check(calibration, table, explicit=explicit, name=cal_path, remedy=hint)


def error_text(exc: Exception) -> str:
    """The message of an error, without Python's ``[Errno N]`` decoration."""
    if isinstance(exc, OSError) and exc.strerror:
        name = exc.filename2 if exc.filename2 is not None else exc.filename
        return f"{name}: {exc.strerror}" if name is not None else exc.strerror
    return str(exc) or type(exc).__name__
