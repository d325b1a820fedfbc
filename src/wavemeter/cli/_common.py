"""What the commands share: option decorators, parameter types, reading, messages."""

from __future__ import annotations

import contextlib

import click
import numpy as np

from ..exceptions import InputError, WavemeterError
from ..io import ColumnRequest, read_table
from ..io._reader import FORMATS, port_key
from ..progress import busy
from ..units import SPEED_OF_LIGHT_M_S, parse_frequency_hz


class FrequencyParam(click.ParamType):
    """A frequency with an optional unit: ``50GHz``, ``49.69 GHz``, ``5e10`` (Hz)."""

    name = "FREQUENCY"

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        try:
            return parse_frequency_hz(value, "value")
        except ValueError as exc:
            self.fail(str(exc), param, ctx)


FREQUENCY = FrequencyParam()


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


def say(quiet: bool, text: str) -> None:
    if not quiet:
        click.echo(text)


def note(quiet: bool, text: str) -> None:
    if not quiet:
        click.echo(f"note: {text}", err=True)


@contextlib.contextmanager
def about(path):
    """Prefix an error raised by the library with the file it concerns."""
    try:
        yield
    except WavemeterError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise type(exc)(f"{path}: {exc}") from exc


# ---------------------------------------------------------------------------- shared options
QUIET = click.option("--quiet", is_flag=True, help="Print nothing but errors.")
FORMAT = click.option(
    "--format",
    "file_format",
    type=click.Choice(FORMATS),
    help="File format (default: from the extension, else CSV).",
)
PORT_PHASES = click.option(
    "--port-phases-deg",
    metavar="DEG,DEG,..",
    help="Nominal port phases (deg) for the conventional method (default 360 j / n).",
)


def setting(name: str, default, kind, help_text: str):
    """An option with a default, shown in ``--help``."""
    return click.option(name, default=default, show_default=True, type=kind, help=help_text)


def out_option(help_text: str):
    """The required ``-o/--out`` file option."""
    return click.option(
        "-o", "--out", "out_path", required=True, type=click.Path(dir_okay=False), help=help_text
    )


def column_options(*, axis: bool = True):
    """Options that choose columns and units of an input file (see DESIGN, input files)."""

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
                "--drop-invalid",
                is_flag=True,
                help="Skip rows with NaN, power-meter sentinels or no light instead of failing.",
            ),
        ]
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
        **extra,
    )


def read(path, request: ColumnRequest, *, need_x: bool, drop_invalid: bool, quiet: bool):
    """Read a data file; with ``drop_invalid`` skip bad rows and say how many.

    Files with known frequencies (``need_x``: sweeps, test files) also get their power
    monitor and temperature columns; readings to measure need neither."""
    with busy(f"reading {path}", quiet=quiet):
        table = read_table(
            path, request, need_x=need_x, find_extras=need_x, allow_invalid=drop_invalid
        )
    if table.invalid.any():
        note(
            quiet,
            f"{path}: skipped {int(table.invalid.sum())} invalid row(s), first: "
            f"{table.describe_invalid(3)}",
        )
    return table


def load(path):
    from ..calibration.files import load_calibration

    return load_calibration(path)


def check_ports(calibration, cal_path, table, explicit: bool) -> None:
    """The file's ports must be the calibration's: same count and, unless chosen with
    --ports, the same names (units aside)."""
    names = ", ".join(table.port_names)
    expected = ", ".join(calibration.port_names_)
    hint = "pass --ports with the file's columns in the calibration's order"
    if len(table.port_names) != calibration.n_ports_:
        raise InputError(
            f"{table.source} has {len(table.port_names)} ports ({names}) but {cal_path} was "
            f"calibrated on {calibration.n_ports_} ({expected}); {hint}"
        )
    if not explicit and [port_key(n) for n in table.port_names] != [
        port_key(n) for n in calibration.port_names_
    ]:
        raise InputError(
            f"{table.source} has ports {names} but {cal_path} was calibrated on ports "
            f"{expected}; {hint}"
        )


def method_label(calibration) -> str:
    return calibration.method_label


def summary_lines(calibration) -> list[str]:
    """Human summary of a fitted calibration."""
    low, high = calibration.span_hz_
    centre = calibration.center_hz_
    design = calibration.get_params()["fsr_hz"]
    lines = [
        f"method           {method_label(calibration)}",
        f"FSR              {calibration.fsr_hz_ / 1e9:.6f} GHz (design {design / 1e9:g} GHz)",
        f"centre           {centre / 1e12:.6f} THz ({SPEED_OF_LIGHT_M_S / centre * 1e9:.4f} nm)",
        f"span             {low / 1e12:.6f} to {high / 1e12:.6f} THz "
        f"({(high - low) / 1e9:.4f} GHz)",
        f"ports            {calibration.n_ports_}: {', '.join(calibration.port_names_)}",
        f"samples          {calibration.n_samples_}",
        f"calibration RMS  {calibration.calibration_rms_hz_ / 1e6:.4f} MHz",
    ]
    if hasattr(calibration, "noise_std_w_"):
        lines.append(f"noise estimate   {calibration.noise_std_w_:.4g} W (calibration residual)")
    if "coarse_hz" in calibration.requires:
        lines.append("windows          centre THz      FSR GHz   samples   RMS MHz")
        for index, window in enumerate(calibration.windows_):
            lines.append(
                f"  {index:<14} {window.center_hz_ / 1e12:>10.6f} {window.fsr_hz_ / 1e9:>12.6f} "
                f"{window.n_samples_:>9} {window.calibration_rms_hz_ / 1e6:>9.4f}"
            )
    return lines
