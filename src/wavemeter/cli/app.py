"""The ``wavemeter`` group: commands are imported only when they run.

``wavemeter --help`` lists the commands from the table below without importing them, so it
costs little more than importing click. Errors: :class:`wavemeter.WavemeterError` and
``OSError`` become one ``error:`` line (control characters stripped, the option that sets
the library parameter at fault named) and exit code 2; anything else is a bug and shows its
traceback. SIGTERM and SIGHUP end a command like Ctrl-C does, so a half-written output's
temporary file is removed; the exit code is 128 + the signal number.

Every :class:`wavemeter.CalibrationWarning` a command's fit emits is printed as one line
``warning: [cause] message`` on stderr, also with ``--quiet`` (a warning is about the
result, not progress); an :class:`~wavemeter.exceptions.InputNote` (how a file was read)
as ``note: message``, once, unless ``--quiet``. Warnings a command refuses (``calibrate
--strict``) arrive as :class:`WarningsRefused`: one ``error: [cause] message`` line each
and exit code 3.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import re
import signal
import sys
import threading
import warnings

import click

from .._version import __version__
from ..exceptions import CalibrationWarning, InputNote, WavemeterError

__all__ = ["main", "cli", "COMMANDS", "OPTION_OF_PARAMETER", "WarningsRefused", "warning_text"]

#: exit codes: bad input, and calibration warnings refused (``--strict``)
EXIT_INPUT_ERROR = 2
EXIT_WARNINGS_REFUSED = 3

#: command -> one-line help shown by ``wavemeter --help``; the module is ``wavemeter.cli.<name>``
COMMANDS = {
    "demo": "Simulate a Table 1 3x3 device, calibrate it, measure, compare with the CRLB.",
    "simulate": "Simulate a sweep of a Table 1 device and write it to a file.",
    "calibrate": "Learn a calibration from a sweep of known frequencies.",
    "measure": "Turn port readings into frequency with a calibration.",
    "stream": "Live readout: a line of frequency for each line of port readings, as it arrives.",
    "evaluate": "Frequency errors on a test file with known frequencies, against the CRLB.",
    "report": "Write an HTML report with figures of a calibration on its sweep.",
    "reanchor": "Re-anchor a calibration to readings of reference lines of known frequency.",
    "info": "Print a summary of a calibration file.",
    "design": "Choose the fewest cascade stages that read a band at a wrong-order rate.",
    "fleet": "Calibrate many devices (a wafer) in parallel on dask: summary and wafer map.",
    "noise": "Frequency noise, linewidth and Allan deviation of a laser from its readings.",
    "serve": "The live instrument: publish readings to many clients, log, metrics, dashboard.",
}


class LazyGroup(click.Group):
    """A group whose commands live in their own modules, imported on first use."""

    def list_commands(self, ctx):
        return list(COMMANDS)

    def get_command(self, ctx, cmd_name):
        if cmd_name not in COMMANDS:
            return None
        return importlib.import_module(f"{__package__}.{cmd_name}").command

    def format_commands(self, ctx, formatter):
        with formatter.section("Commands"):
            formatter.write_dl(list(COMMANDS.items()))


@click.group(
    cls=LazyGroup,
    context_settings={"help_option_names": ["-h", "--help"]},
    invoke_without_command=True,
)
@click.version_option(__version__, prog_name="wavemeter")
@click.pass_context
def cli(ctx):
    """Calibrate multi-port interferometric wavelength meters and retrieve frequency.

    \b
    Example:
      wavemeter simulate -o sweep.csv --test 20000
      wavemeter calibrate sweep.csv -o chip.wmcal.json --fsr 50GHz
      wavemeter measure chip.wmcal.json sweep-test.csv -o frequencies.csv
      wavemeter evaluate chip.wmcal.json sweep-test.csv --sweep sweep.csv
    """
    if ctx.invoked_subcommand is None:
        click.echo(ctx.get_help())


#: library parameter (``InputError.parameter``, or named in a message) -> the option that
#: sets it; a command may name it differently. A hint is given only when the running
#: command has that option.
OPTION_OF_PARAMETER = {
    "force": "--force",
    "fsr_hz": "--fsr",
    "fsr_tolerance": "--fsr-tolerance",
    "x": "--x",
    "x_unit": "--x-unit",
    "ports": "--ports",
    "power_unit": "--power-unit",
    "allow_invalid": "--drop-invalid",
    "monitor": "--monitor",
    "temperature": "--temperature",
    "temperature_k": "--temperature-k",
    "temperature_std_k": "--temperature-std-k",
    "coarse": "--coarse",
    "coarse_hz": "--coarse-frequency",
    "keep": "--keep",
    "port_phases_rad": "--port-phases-deg",
    "retrieval": "--retrieval",
    "file_format": "--format",
    "power_w": "--power",
    "noise_w": "--noise",
    "samples": "--samples",
    "span_fsr": "--span-fsr",
    "power_fluctuation": "--power-fluctuation",
    "dispersion_s2": "--dispersion",
    "coupler_slope_per_thz": "--coupler-slope",
    "responsivity_slope_per_thz": "--responsivity-slope",
    "phase_order": "--phase-order",
    "map_order": "--map-order",
    "stage_ports": "--stage-ports",
    "max_order_error": "--max-order-error",
    "delimiter": "--delimiter",
    "decimal": "--decimal",
    "per_fsr": "--per-fsr",
    "dark_w": "--dark-w",
    "dark_file": "--dark",
    "uncertainty": "--uncertainty",
    "reference_column": "--reference-column",
    "reference_transmission": "--reference-column",
    "reference_lines": "--lines",
    "band_hz": "--band",
    "reference_pressure_pa": "--cell-pressure",
    "reference_pressure_std_pa": "--cell-pressure-std",
    "axis_error_hz": "--axis-error",
    "sweep_axis": "--sweep-axis",
    "reference_cell": "--reference-cell",
}
_OPTION_IN_COMMAND = {
    "simulate": {"x_unit": "--write-axis-unit", "power_unit": "--write-power-unit"},
    "design": {
        "band_hz": "--band",
        "finest_fsr_hz": "--finest-fsr",
        "power_w": "--power",
        "noise_w": "--noise",
        "ports": "--ports",
        "wrong_order_rate": "--rate",
        "stages": "--stages",
        "noise_factor": "--noise-factor",
    },
    "noise": {
        "rate_hz": "--rate",
        "time_column": "--time-column",
        "observation_time_s": "--observation-time",
    },
}


def _command_name(argv) -> str | None:
    args = sys.argv[1:] if argv is None else list(argv)
    return next((arg for arg in args if not arg.startswith("-")), None)


def _with_options(exc: Exception, message: str, command_name: str | None) -> str:
    """The message in the running command's words: a parameter it names in parentheses,
    ``name them (ports)``, becomes the option, ``(--ports)``; then `` (use --force)`` or
    `` (fsr_tolerance: --fsr-tolerance, fsr_hz: --fsr)``: the options that set the other
    parameters the error is about (those the message does not name already)."""
    if command_name not in COMMANDS:
        return message
    command = cli.get_command(None, command_name)
    commands = [command, *getattr(command, "commands", {}).values()]  # a group's too
    flags = {flag for each in commands for param in each.params for flag in param.opts}
    options = {**OPTION_OF_PARAMETER, **_OPTION_IN_COMMAND.get(command_name, {})}
    for name, flag in options.items():
        if flag in flags:
            message = message.replace(f"({name})", f"({flag})")
    return message + _option_hint(exc, message, flags, options)


def _option_hint(exc: Exception, message: str, flags: set, options: dict) -> str:
    """The hint `` (use --force)`` of :func:`_with_options`."""
    parameter = getattr(exc, "parameter", None)
    found = {
        name: match.start()
        for name in OPTION_OF_PARAMETER
        if ("_" in name or name == parameter)
        and (match := re.search(rf"\b{name}\b", message)) is not None
    }
    named = sorted(found, key=found.get)
    wanted = list(dict.fromkeys([*([parameter] if parameter else []), *named]))
    parts = [
        f"{name}: {options[name]}" if name in named else f"use {options[name]}"
        for name in wanted
        if options.get(name) in flags
        and not re.search(rf"(?<![\w-]){re.escape(options[name])}(?![\w-])", message)
    ]
    return f" ({', '.join(parts)})" if parts else ""


def _one_line(prefix: str, text: str) -> str:
    """``prefix`` and ``text`` on one line, without control characters (imported when
    first printed: ``--help`` loads no numpy)."""
    from ._common import one_line

    return one_line(prefix, text)


def _usage_text(exc: click.ClickException) -> str:
    """Click's message, pointing at the help of the command whose usage was wrong (a bad
    value's message already says what is allowed)."""
    message = exc.format_message()
    context = getattr(exc, "ctx", None)
    bad_value = isinstance(exc, click.BadParameter) and not isinstance(exc, click.MissingParameter)
    if isinstance(exc, click.UsageError) and not bad_value and context is not None:
        return f"{message.rstrip('.')} (see '{context.command_path} --help')"
    return message


def _error_line(text: str) -> str:
    """``error: text`` on one line, without control characters."""
    return _one_line("error: ", text)


class WarningsRefused(Exception):
    """Calibration warnings a command was told to refuse (``--strict``); nothing was written.

    Not a :class:`WavemeterError`: the input was read and fitted, but the result is not
    trusted. :func:`main` prints one ``error:`` line per warning and returns exit code 3.

    Parameters
    ----------
    refused : sequence of CalibrationWarning
        The warnings, in the order the fit emitted them.
    consequence : str
        What did not happen because of them, appended to every line in brackets
        (``"--strict: no calibration written"``).
    """

    def __init__(self, refused, consequence: str):
        super().__init__(f"{len(refused)} calibration warning(s) refused")
        self.refused = list(refused)
        self.consequence = consequence


class Refused(Exception):
    """A result a command was told to refuse (``--strict``) for what it found in the input
    (readings the calibration cannot read); nothing was written. :func:`main` prints its
    ``error:`` line and returns exit code 3."""


#: calibration-warning cause -> the command-line options of its remedy (the library's
#: messages name parameters: power_monitor_w, dark_w, retrieval, CalibrationSet)
OPTIONS_OF_CAUSE = {
    "power_drift": "--monitor COL",
    "detector_offset": "--dark FILE or --dark-w",
    "dispersion": "--method wideband (or --per-fsr)",
    "unequal_noise": "--retrieval ml",
    "ill_conditioned": "--retrieval ml",
    "phase_drift": "--method thermal with a temperature column",
    "temperature_noise": "--temperature-std-k",
}


#: a remedy that names one of these settings or classes is done with its option, whatever
#: the cause (a wide-band fit whose phase order is too low: ``dispersion``, remedied by its
#: order; a misfit no cause explains over many FSRs: the wide-band calibration)
OPTIONS_OF_REMEDY_NAME = {
    "phase_order": "--phase-order",
    "map_order": "--map-order",
    "WidebandCalibrator": "--method wideband (or --per-fsr)",
}


def warning_text(warning: Warning) -> str:
    """``[cause] message`` of a calibration warning, on one line (``other_misfit`` when the
    warning names no cause), with the options of its remedy where it has some."""
    cause = getattr(warning, "cause", "other_misfit")
    remedy = getattr(warning, "remedy", "")
    named = [option for name, option in OPTIONS_OF_REMEDY_NAME.items() if name in remedy]
    hint = ", ".join(named) if named else OPTIONS_OF_CAUSE.get(cause)
    return f"[{cause}] {warning}" + (f" (options: {hint})" if hint else "")


@contextlib.contextmanager
def _calibration_warnings_as_lines():
    """While a command runs, print every :class:`CalibrationWarning` as one ``warning:``
    line on stderr, each time it is emitted (not once per place, as Python does by
    default); other warnings are shown as before."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", CalibrationWarning)
        warnings.simplefilter("always", InputNote)
        show_other = warnings.showwarning
        noted = set()

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, CalibrationWarning):
                click.echo(_one_line("warning: ", warning_text(message)), err=True)
            elif issubclass(category, InputNote):
                context = click.get_current_context(silent=True)
                quiet = context is not None and context.params.get("quiet")
                if not quiet and str(message) not in noted:
                    click.echo(_one_line("note: ", str(message)), err=True)
                noted.add(str(message))
            else:
                show_other(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        yield


def _exit_on_signal(signum, frame):
    raise SystemExit(128 + signum)


@contextlib.contextmanager
def _signals_end_the_command():
    """SIGTERM and SIGHUP raise SystemExit(128 + signum) while a command runs, so that
    cleanup (temporary files) happens as for Ctrl-C; the old handlers come back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for name in ("SIGTERM", "SIGHUP"):
        number = getattr(signal, name, None)
        if number is not None:
            previous[number] = signal.signal(number, _exit_on_signal)
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def main(argv=None) -> int:
    """Run the command line; return the exit code (0 ok, 2 user error, 3 calibration
    warnings or unreadable readings refused by ``--strict``, 130 interrupted)."""
    # Our products are skinny (readings x 3): OpenBLAS threads only add start-up and, on a
    # busy machine, spin against each other (a 2000-sample fit 10x slower). One thread,
    # unless the user chose; set before numpy loads (no command has imported it yet).
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    try:
        with _signals_end_the_command(), _calibration_warnings_as_lines():
            # without standalone mode click returns the code of a command's ctx.exit(code)
            code = cli.main(args=argv, prog_name="wavemeter", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        click.echo("error: interrupted", err=True)
        return 130
    except click.ClickException as exc:
        click.echo(_error_line(_usage_text(exc)), err=True)
        return EXIT_INPUT_ERROR
    except WarningsRefused as exc:
        for warning in exc.refused:
            click.echo(_error_line(f"{warning_text(warning)} ({exc.consequence})"), err=True)
        return EXIT_WARNINGS_REFUSED
    except Refused as exc:
        click.echo(_error_line(str(exc)), err=True)
        return EXIT_WARNINGS_REFUSED
    except (WavemeterError, OSError) as exc:
        from ._common import error_text

        message = error_text(exc)
        click.echo(_error_line(_with_options(exc, message, _command_name(argv))), err=True)
        return EXIT_INPUT_ERROR
    return code if isinstance(code, int) else 0


if __name__ == "__main__":
    sys.exit(main())
