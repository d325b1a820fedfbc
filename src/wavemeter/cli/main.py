"""Command-line interface: ``wavemeter COMMAND ...``.

User errors (bad files, values, options) print one line ``error: ...`` on stderr and exit
with code 2; no traceback, no partial output file.
"""

from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

import click
import numpy as np

from .._version import __version__
from ..exceptions import InputError, WavemeterError
from ..io._reader import (
    FORMATS,
    SENTINEL_DBM,
    ColumnRequest,
    port_key,
    read_table,
    table_format,
    write_table,
)
from ..progress import busy, chunked
from ..report.demo import run_demo
from ..units import SPEED_OF_LIGHT_M_S, canonical_unit, hz_to_axis, parse_frequency_hz, w_to_power

__all__ = ["main", "cli"]

USER_ERRORS = (WavemeterError, OSError)
METHODS = ("learned", "conventional")


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


def _names(text: str | None) -> tuple[str, ...] | None:
    """Comma-separated column names, or None."""
    if text is None:
        return None
    names = tuple(name.strip() for name in text.split(","))
    if not all(names):
        raise InputError(f"empty column name in {text!r}; separate names with single commas")
    return names


def _port_phases_rad(text: str | None) -> np.ndarray | None:
    if text is None:
        return None
    try:
        return np.deg2rad([float(value) for value in text.split(",")])
    except ValueError as exc:
        raise InputError(
            f"--port-phases-deg must be numbers separated by commas, got {text!r}"
        ) from exc


def _say(quiet: bool, text: str) -> None:
    if not quiet:
        click.echo(text)


def _note(quiet: bool, text: str) -> None:
    if not quiet:
        click.echo(f"note: {text}", err=True)


@contextlib.contextmanager
def _about(path):
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


def _request(options: dict, **extra) -> ColumnRequest:
    return ColumnRequest(
        x=options.get("x_column"),
        x_unit=options.get("x_unit"),
        ports=_names(options.get("ports_columns")),
        power_unit=options.get("power_unit"),
        monitor=options.get("monitor_column"),
        temperature=options.get("temperature_column"),
        **extra,
    )


def _read(path, request: ColumnRequest, *, need_x: bool, drop_invalid: bool, quiet: bool):
    """Read a data file; with ``drop_invalid`` skip bad rows and say how many.

    Files with known frequencies (``need_x``: sweeps, test files) also get their power
    monitor and temperature columns; readings to measure need neither."""
    with busy(f"reading {path}", quiet=quiet):
        table = read_table(
            path, request, need_x=need_x, find_extras=need_x, allow_invalid=drop_invalid
        )
    if table.invalid.any():
        _note(
            quiet,
            f"{path}: skipped {int(table.invalid.sum())} invalid row(s), first: "
            f"{table.describe_invalid(3)}",
        )
    return table


def _load(path):
    from ..calibration.files import load_calibration

    return load_calibration(path)


def _is_set(calibration) -> bool:
    from ..calibration.set import CalibrationSet

    return isinstance(calibration, CalibrationSet)


def _check_ports(calibration, cal_path, table, explicit: bool) -> None:
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


# ---------------------------------------------------------------------------- the group
@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="wavemeter")
def cli():
    """Calibrate multi-port interferometric wavelength meters and retrieve frequency.

    \b
    Example:
      wavemeter simulate -o sweep.csv --test 20000
      wavemeter calibrate sweep.csv -o chip.wmcal.json --fsr 50GHz
      wavemeter measure chip.wmcal.json readings.csv -o frequencies.csv
      wavemeter evaluate chip.wmcal.json sweep-test.csv --sweep sweep.csv
    """


@cli.command()
@click.option(
    "--out",
    "out_dir",
    default="wavemeter-demo",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Folder for the sweep, calibration and results files.",
)
@click.option("--seed", default=1, show_default=True, help="Seed of the simulated device.")
@QUIET
def demo(out_dir, seed, quiet):
    """Simulate a Table 1 3x3 device, calibrate it, measure, compare with the CRLB.

    \b
    Example:
      wavemeter demo --out ./wavemeter-demo
    """
    run_demo(out_dir, seed=seed, quiet=quiet)


# ---------------------------------------------------------------------------- simulate
def _suffix(unit: str) -> str:
    """Unit suffix of a column name: ``frequency_hz``, ``p1_w``, ``freq_THz``, ``p1_dBm``."""
    return unit.lower() if unit in ("Hz", "W") else unit


def _axis_column(unit: str, prefix: str = "") -> str:
    word = "frequency" if unit.endswith("Hz") else "wavelength"
    return f"{prefix}{word}_{_suffix(unit)}"


def _power_columns(powers_w: np.ndarray, unit: str) -> dict[str, np.ndarray]:
    """Port columns ``p1_<unit>``...; in dBm a reading <= 0 W becomes the -200 dBm code."""
    values = w_to_power(powers_w, unit)
    if unit == "dBm":
        values = np.where(np.isfinite(values), values, SENTINEL_DBM)
    return {f"p{k + 1}_{_suffix(unit)}": values[:, k] for k in range(powers_w.shape[1])}


def _readings(device, frequency_hz, options, rng) -> dict[str, np.ndarray]:
    """Port columns (and, with a power fluctuation, a monitor) for frequencies (Hz)."""
    samples = frequency_hz.size
    power = np.full(samples, options["power_w"])
    if options["power_fluctuation"] > 0:
        power = power * (1 + options["power_fluctuation"] * rng.standard_normal(samples))
    powers = np.empty((samples, device.ports))
    for rows in chunked(samples, "simulating", quiet=options["quiet"]):
        powers[rows] = device.powers(frequency_hz[rows], power[rows], options["noise_w"], rng)
    columns = _power_columns(powers, options["power_unit"])
    if options["power_fluctuation"] > 0:
        unit = options["power_unit"]
        columns[f"monitor_{_suffix(unit)}"] = w_to_power(device.monitor(power), unit)
    return columns


@cli.command()
@out_option("Sweep file to write (.csv, .tsv, .parquet, .h5, .npz).")
@setting("--ports", 3, click.IntRange(3, 64), "Number of output ports of the MMI.")
@setting("--seed", 1, int, "Seed of the device impairments and the noise.")
@setting("--samples", 2001, click.IntRange(4), "Readings in the calibration sweep.")
@setting("--span-fsr", 1.0, click.FloatRange(0, min_open=True), "Sweep span in FSRs.")
@setting("--power-w", 1e-3, click.FloatRange(0, min_open=True), "Source power (W).")
@setting(
    "--noise-w", 5e-7, click.FloatRange(0), "Detector noise standard deviation per reading (W)."
)
@setting(
    "--fsr", "50GHz", FREQUENCY, "Design FSR (the device's differs by Table 1's 5 % delay spread)."
)
@click.option(
    "--test",
    "test_samples",
    default=0,
    type=click.IntRange(0),
    help="Also write this many readings at random frequencies with a truth column.",
)
@click.option(
    "--test-out",
    type=click.Path(dir_okay=False),
    help="Test file (default: OUT with '-test' before the extension).",
)
@setting(
    "--x-unit",
    "Hz",
    None,
    "Axis unit written: Hz..THz gives frequency_<unit>, nm/um/m wavelength_<unit>.",
)
@setting(
    "--power-unit",
    "W",
    None,
    "Port unit written: W, mW, uW, nW or dBm (a reading <= 0 W is -200 dBm).",
)
@setting(
    "--power-fluctuation",
    0.0,
    click.FloatRange(0, 0.3),
    "Relative std of the source power per reading; > 0 adds a monitor column.",
)
@FORMAT
@QUIET
def simulate(out_path, test_samples, test_out, **options):
    """Simulate a sweep of a Table 1 device (paper Section III) and write it to a file.

    \b
    Example:
      wavemeter simulate -o sweep.csv --ports 3 --seed 1 --test 20000
      wavemeter simulate -o lab.csv --x-unit nm --power-unit dBm --noise-w 2e-8
    """
    from ..simulation.interferometer import Interferometer

    x_unit = canonical_unit(options["x_unit"], "axis", "--x-unit")
    options["power_unit"] = canonical_unit(options["power_unit"], "power", "--power-unit")
    if options["power_unit"] == "V":
        raise InputError("--power-unit V is not a simulated output; use W, mW, uW, nW or dBm")
    device = Interferometer.table1(options["ports"], seed=options["seed"], fsr_hz=options["fsr"])
    rng = np.random.default_rng(options["seed"])  # as the demo: the same seed, the same data
    sweep_hz = device.sweep_hz(options["samples"], options["span_fsr"])
    files = [(Path(out_path), _axis_column(x_unit), sweep_hz)]
    if test_samples:
        low, high = sweep_hz[0], sweep_hz[-1]
        target = (
            Path(test_out) if test_out else Path(out_path).with_stem(f"{Path(out_path).stem}-test")
        )
        files.append((target, _axis_column(x_unit, "true_"), rng.uniform(low, high, test_samples)))
    tables = [
        (path, {axis: hz_to_axis(frequency, x_unit), **_readings(device, frequency, options, rng)})
        for path, axis, frequency in files
    ]
    for path, _ in tables:  # check every target before writing any: no partial output
        table_format(path, options["file_format"])
        if not path.absolute().parent.is_dir():
            raise InputError(f"cannot write {path}: folder {path.parent} does not exist")
    for path, columns in tables:
        write_table(path, columns, options["file_format"])
        rows = len(next(iter(columns.values())))
        _say(options["quiet"], f"wrote {path} ({rows} rows: {', '.join(columns)})")
        codes = sum(int(np.count_nonzero(values == SENTINEL_DBM)) for values in columns.values())
        if options["power_unit"] == "dBm" and codes:
            _say(
                options["quiet"],
                f"note: {codes} reading(s) at or below 0 W (noise at a fringe null) are written "
                f"as the {SENTINEL_DBM:g} dBm no-reading code; read {path} with --drop-invalid, "
                "or simulate with a lower --noise-w",
            )
    _say(
        options["quiet"],
        f"device: Table 1, {device.ports} ports, seed {options['seed']}, true FSR "
        f"{device.true_fsr_hz / 1e9:.6f} GHz, centre {device.center_hz / 1e12:.6f} THz",
    )


# ---------------------------------------------------------------------------- calibrate
def _fit(options: dict, table, phases):
    from ..calibration.baselines import ConventionalCalibrator
    from ..calibration.learned import Calibrator
    from ..calibration.set import CalibrationSet

    fsr, tolerance, method = options["fsr"], options["fsr_tolerance"], options["method"]
    retrieval = options["retrieval"]
    if method != "learned" and retrieval != "pinv":
        raise InputError(f"--retrieval {retrieval} needs --method learned, got --method {method}")
    if method == "learned":
        calibrator = Calibrator(fsr_hz=fsr, fsr_tolerance=tolerance, retrieval=retrieval)
    else:
        calibrator = ConventionalCalibrator(fsr_hz=fsr, port_phases_rad=phases)
    if options["per_fsr"]:
        calibrator = CalibrationSet(fsr, tolerance, window=calibrator)
    with busy(f"calibrating on {table.source}", quiet=options["quiet"]), _about(table.source):
        return calibrator.fit(table.powers_w, table.x_hz, table.monitor_w, list(table.port_names))


def _metadata(table) -> dict:
    """What the calibration was read from, kept in the calibration file."""
    temperature = table.temperature_k
    return {
        "sweep_file": str(table.source),
        "x_column": table.x_column,
        "x_unit": table.x_unit,
        "port_columns": list(table.port_names),
        "port_units": list(table.port_units),
        "monitor_column": table.monitor_column,
        "temperature_column": table.temperature_column,
        "temperature_k_range": None
        if temperature is None
        else [float(temperature.min()), float(temperature.max())],
        "rows": table.n_rows,
        "dropped_rows": table.dropped_rows,
    }


@cli.command()
@click.argument("sweep", type=click.Path(dir_okay=False))
@out_option("Calibration file to write (JSON, e.g. chip.wmcal.json).")
@setting("--fsr", "50GHz", FREQUENCY, "Design FSR: 50GHz, '49.69 GHz', 5e10 (Hz).")
@setting(
    "--fsr-tolerance",
    0.2,
    click.FloatRange(0, 1, min_open=True, max_open=True),
    "Relative half width of the FSR search (learned method).",
)
@click.option(
    "--method",
    type=click.Choice(METHODS),
    default="learned",
    show_default=True,
    help="Learned linear map (paper) or the conventional ideal-map method.",
)
@click.option(
    "--retrieval",
    type=click.Choice(("pinv", "ml")),
    default="pinv",
    show_default=True,
    help="Phase retrieval of the learned method: pseudo-inverse (paper) or cone-constrained "
    "maximum likelihood (reaches the Cramer-Rao bound also for ill-conditioned maps).",
)
@PORT_PHASES
@click.option(
    "--per-fsr",
    is_flag=True,
    help="Calibrate each FSR of a multi-FSR sweep on its own (a calibration set).",
)
@column_options()
@QUIET
def calibrate(sweep, out_path, port_phases_deg, **options):
    """Learn a calibration from a sweep of known frequencies.

    SWEEP is a CSV/TSV, HDF5, MAT, NPZ or Parquet file with a frequency or wavelength
    column and three or more port columns.

    \b
    Example:
      wavemeter calibrate sweep.csv -o chip.wmcal.json --fsr 50GHz
      wavemeter calibrate lab.csv -o chip.wmcal.json --fsr '49.69 GHz' \\
          --x 'Wavelength (nm)' --ports 'Port 1 [dBm]','Port 2 [dBm]','Port 3 [dBm]'
    """
    from ..calibration.files import save_calibration

    request = _request(options)
    table = _read(
        sweep, request, need_x=True, drop_invalid=options["drop_invalid"], quiet=options["quiet"]
    ).valid_only()
    calibration = _fit(options, table, _port_phases_rad(port_phases_deg))
    save_calibration(calibration, out_path, _metadata(table))
    if not options["quiet"]:
        click.echo(
            f"calibrated {sweep}: {table.n_rows} rows, axis {table.x_column} ({table.x_unit}), "
            f"ports {', '.join(table.port_names)}"
            + (f", monitor {table.monitor_column}" if table.monitor_column else "")
        )
        click.echo("\n".join(_summary_lines(calibration)))
        click.echo(f"wrote {out_path}")


# ---------------------------------------------------------------------------- measure
def _coarse(calibration, cal_path, table, coarse_hz):
    """Coarse frequency per reading for a calibration set (None for a single map)."""
    if not _is_set(calibration):
        return None
    if table.coarse_hz is not None:
        return table.coarse_hz
    if coarse_hz is not None:
        return np.full(table.n_rows, coarse_hz)
    low, high = calibration.covered_hz()
    raise InputError(
        f"{cal_path} is a per-FSR calibration set ({len(calibration.windows_)} windows, "
        f"{low / 1e12:.6f} to {high / 1e12:.6f} THz): it needs a coarse frequency per "
        "reading to pick the window; pass --coarse COL or --coarse-hz VALUE"
    )


@cli.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("data", type=click.Path(dir_okay=False))
@out_option("Output file: frequency_hz, wavelength_nm, phase_rad per input row.")
@click.option("--keep", metavar="COL,COL,..", help="Input columns to copy into the output.")
@FORMAT
@click.option(
    "--coarse",
    "coarse_column",
    metavar="COL",
    help="Coarse frequency or wavelength column (calibration sets).",
)
@click.option(
    "--coarse-hz",
    type=FREQUENCY,
    help="One coarse frequency for every reading, e.g. 193.4THz (calibration sets).",
)
@click.option(
    "--uncertainty",
    is_flag=True,
    help="Also write frequency_std_hz: the per-reading Cramer-Rao bound at the detector noise "
    "estimated from the calibration (learned single-map calibrations).",
)
@column_options(axis=False)
@QUIET
def measure(
    calibration_file,
    data,
    out_path,
    keep,
    file_format,
    coarse_column,
    coarse_hz,
    uncertainty,
    **options,
):
    """Turn port readings into frequency with a calibration.

    Writes one row per input row, in order: frequency_hz, wavelength_nm (vacuum) and
    phase_rad at full float64 precision, with --uncertainty frequency_std_hz, then the
    --keep columns. Rows skipped with --drop-invalid are written as NaN.

    \b
    Example:
      wavemeter measure chip.wmcal.json readings.csv -o frequencies.csv --keep time_s
    """
    calibration = _load(calibration_file)
    table_format(out_path, file_format)  # reject a bad format before the work
    if uncertainty and "frequency_std" not in calibration.capabilities:
        raise InputError(
            f"{calibration_file}: --uncertainty needs a learned calibration (single or per "
            f"FSR), not a {_method_label(calibration)} calibration"
        )
    request = _request(options, coarse=coarse_column, keep=_names(keep) or ())
    table = _read(
        data, request, need_x=False, drop_invalid=options["drop_invalid"], quiet=options["quiet"]
    )
    _check_ports(calibration, calibration_file, table, explicit=request.ports is not None)
    valid = table.valid_only()
    coarse = _coarse(calibration, calibration_file, valid, coarse_hz)
    frequency = np.full(table.n_rows, np.nan)
    phase = np.full(table.n_rows, np.nan)
    std = np.full(table.n_rows, np.nan)
    rows = np.flatnonzero(~table.invalid)
    for block in chunked(valid.n_rows, f"measuring {data}", quiet=options["quiet"]):
        extra = {} if coarse is None else {"coarse_hz": coarse[block]}
        with _about(data):
            frequency[rows[block]] = calibration.predict(valid.powers_w[block], **extra)
            phase[rows[block]] = calibration.phase(valid.powers_w[block], **extra)
            if uncertainty:
                std[rows[block]] = calibration.frequency_std_hz(valid.powers_w[block], **extra)
    columns = {
        "frequency_hz": frequency,
        "wavelength_nm": SPEED_OF_LIGHT_M_S / frequency * 1e9,
        "phase_rad": phase,
        **({"frequency_std_hz": std} if uncertainty else {}),
    }
    for name, values in table.kept.items():
        columns.setdefault(name, values)
    with busy(f"writing {out_path}", quiet=options["quiet"]):
        write_table(out_path, columns, file_format)
    _say(options["quiet"], f"wrote {out_path} ({table.n_rows} rows)")


# ---------------------------------------------------------------------------- evaluate
def _noise_std_w(calibration) -> float:
    """Detector noise (W) of a learned calibration's residual (mean over a set's windows)."""
    if _is_set(calibration):
        return float(np.mean([window.noise_std_w_ for window in calibration.windows_]))
    return calibration.noise_std_w_


def _method_label(calibration) -> str:
    return calibration.method_label


def _other_method(calibration, sweep, options, phases):
    """The other method (learned <-> conventional) fitted on the sweep file."""
    from ..report.html import comparison_calibration

    request = _request(options)
    table = _read(
        sweep, request, need_x=True, drop_invalid=options["drop_invalid"], quiet=options["quiet"]
    ).valid_only()
    _check_ports(calibration, "the calibration", table, request.ports is not None)
    with _about(sweep):
        return comparison_calibration(
            calibration, table.powers_w, table.x_hz, table.monitor_w, phases
        )


def _evaluation(calibrations: dict, table) -> dict:
    """Error summaries (Hz) of each calibration on a table with known frequencies, and the
    Cramer-Rao bound of the first learned one."""
    from ..analysis.metrics import error_summary_hz, frequency_error_hz
    from ..report.html import crlb_per_reading_hz

    truth = table.x_hz
    coarse = table.coarse_hz if table.coarse_hz is not None else truth
    results, bound, noise = {}, None, None
    for label, calibration in calibrations.items():
        extra = {"coarse_hz": coarse} if _is_set(calibration) else {}
        predicted = calibration.predict(table.powers_w, **extra)
        error = frequency_error_hz(predicted, truth, calibration.fsr_hz_)
        results[label] = error_summary_hz(error)
        if bound is None:
            bound = crlb_per_reading_hz(calibration, table.powers_w, truth)
            noise = None if bound is None else _noise_std_w(calibration)
    summary = {"methods": results, "crlb_rms_hz": None, "noise_std_w": noise}
    if bound is not None:
        crlb_rms = float(np.sqrt(np.mean(bound**2)))
        summary["crlb_rms_hz"] = crlb_rms
        for stats in results.values():
            stats["rms_over_crlb"] = stats["rms_hz"] / crlb_rms
    return summary


def _print_evaluation(report: dict) -> None:
    click.echo(
        f"{report['test_file']}: {report['samples']} readings, truth {report['truth_column']} "
        f"({report['truth_unit']})"
    )
    width = max(len(label) for label in report["methods"]) + 2
    header = ("RMS MHz", "max MHz", "p95 MHz", "p99 MHz", "RMS/CRLB")
    click.echo(f"{'method':<{width}}" + "".join(f"{h:>12}" for h in header))
    for label, stats in report["methods"].items():
        ratio = stats.get("rms_over_crlb")
        cells = [stats[key] / 1e6 for key in ("rms_hz", "max_hz", "p95_hz", "p99_hz")]
        click.echo(
            f"{label:<{width}}"
            + "".join(f"{value:>12.4f}" for value in cells)
            + (f"{ratio:>12.3f}" if ratio is not None else f"{'-':>12}")
        )
    if report["crlb_rms_hz"] is not None:
        click.echo(
            f"CRLB {report['crlb_rms_hz'] / 1e6:.4f} MHz RMS (noise {report['noise_std_w']:.3g} "
            "from the calibration residual, learned map as the true one)"
        )
    if "adjacent" in report:
        adjacent = report["adjacent"]
        click.echo(
            f"adjacent FSR ({adjacent['windows_evaluated']} windows): "
            + ", ".join(
                f"{name} RMS {adjacent[name]['rms_hz'] / 1e6:.4f} MHz"
                for name in ("own", "adjacent", "conventional_own", "conventional_adjacent")
            )
        )


@cli.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("test", type=click.Path(dir_okay=False))
@click.option(
    "--sweep",
    type=click.Path(dir_okay=False),
    help="Sweep to fit the other method (learned <-> conventional) for comparison.",
)
@click.option(
    "--compare",
    "compare_files",
    multiple=True,
    type=click.Path(dir_okay=False),
    help="Another calibration file to evaluate side by side (repeatable).",
)
@PORT_PHASES
@click.option(
    "--coarse",
    "coarse_column",
    metavar="COL",
    help="Coarse frequency column for a calibration set (default: the truth).",
)
@click.option(
    "--adjacent",
    is_flag=True,
    help="Also apply each FSR window's map to the neighbouring FSRs (paper Fig. 9).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the results as JSON.")
@column_options()
@QUIET
def evaluate(
    calibration_file,
    test,
    sweep,
    compare_files,
    port_phases_deg,
    coarse_column,
    adjacent,
    as_json,
    **options,
):
    """Frequency errors on a test file with known frequencies, against the CRLB.

    Reports RMS, max, 95th and 99th percentile |error| (MHz) of CAL, of each --compare
    calibration and, with --sweep, of the other method fitted on that sweep; errors are
    taken modulo the FSR. RMS/CRLB divides by the Cramer-Rao bound of the learned map
    with the noise estimated from its calibration residual (a residual holding
    unmodelled structure makes that bound loose). A calibration set picks each reading's
    window from --coarse, else from the truth.

    \b
    Example:
      wavemeter evaluate chip.wmcal.json sweep-test.csv --sweep sweep.csv
      wavemeter evaluate set.wmcal.json test.csv --adjacent --json
    """
    calibration = _load(calibration_file)
    request = _request(options, coarse=coarse_column)
    table = _read(
        test,
        request,
        need_x=True,
        drop_invalid=options["drop_invalid"],
        quiet=options["quiet"] or as_json,
    ).valid_only()
    explicit = request.ports is not None
    _check_ports(calibration, calibration_file, table, explicit)
    calibrations = {_method_label(calibration): calibration}
    for path in compare_files:
        other = _load(path)
        _check_ports(other, path, table, explicit)
        calibrations.setdefault(f"{_method_label(other)} ({Path(path).name})", other)
    if sweep is not None:
        other = _other_method(calibration, sweep, options, _port_phases_rad(port_phases_deg))
        calibrations[f"{_method_label(other)} (fitted on {Path(sweep).name})"] = other
    report = {
        "calibration_file": str(calibration_file),
        "test_file": str(test),
        "samples": table.n_rows,
        "dropped_rows": table.dropped_rows,
        "truth_column": table.x_column,
        "truth_unit": table.x_unit,
    }
    with _about(test):
        report.update(_evaluation(calibrations, table))
    if adjacent:
        if not _is_set(calibration):
            raise InputError(
                f"--adjacent needs a per-FSR calibration set; {calibration_file} is a single "
                "calibration: calibrate with --per-fsr on a sweep over several FSRs"
            )
        with _about(test):
            from ..analysis.evaluation import adjacent_evaluation
            from ..calibration.baselines import ConventionalCalibrator

            phases = _port_phases_rad(port_phases_deg)
            if phases is None:
                phases = calibration.windows_[0].get_params().get("port_phases_rad")
            baseline = ConventionalCalibrator(port_phases_rad=phases)
            report["adjacent"] = adjacent_evaluation(
                calibration, table.powers_w, table.x_hz, baseline
            )
    if as_json:
        click.echo(json.dumps(report, indent=1))
    elif not options["quiet"]:
        _print_evaluation(report)


# ---------------------------------------------------------------------------- report
@cli.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("sweep", type=click.Path(dir_okay=False))
@click.argument("test", required=False, type=click.Path(dir_okay=False))
@out_option("HTML report to write; figures go beside it as PNG files.")
@PORT_PHASES
@column_options()
@QUIET
def report(calibration_file, sweep, test, out_path, port_phases_deg, **options):
    """Write an HTML report with figures of a calibration on its sweep (and a test file).

    \b
    Example:
      wavemeter report chip.wmcal.json sweep.csv sweep-test.csv -o report.html
    """
    from ..report.html import write_report

    calibration = _load(calibration_file)
    request = _request(options)
    tables = []
    for path in (sweep, test):
        if path is None:
            tables.append(None)
            continue
        table = _read(
            path, request, need_x=True, drop_invalid=options["drop_invalid"], quiet=options["quiet"]
        ).valid_only()
        _check_ports(calibration, calibration_file, table, request.ports is not None)
        tables.append(table)
    with busy(f"writing {out_path}", quiet=options["quiet"]):
        written = write_report(
            calibration,
            tables[0],
            tables[1],
            out_html=out_path,
            port_phases_rad=_port_phases_rad(port_phases_deg),
        )
    _say(options["quiet"], f"wrote {', '.join(str(path) for path in written)}")


# ---------------------------------------------------------------------------- info
def _summary_lines(calibration) -> list[str]:
    """Human summary of a fitted calibration."""
    low, high = calibration.span_hz_
    centre = calibration.center_hz_
    design = calibration.get_params()["fsr_hz"]
    lines = [
        f"method           {_method_label(calibration)}",
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
    if _is_set(calibration):
        lines.append("windows          centre THz      FSR GHz   samples   RMS MHz")
        for index, window in enumerate(calibration.windows_):
            lines.append(
                f"  {index:<14} {window.center_hz_ / 1e12:>10.6f} {window.fsr_hz_ / 1e9:>12.6f} "
                f"{window.n_samples_:>9} {window.calibration_rms_hz_ / 1e6:>9.4f}"
            )
    return lines


@cli.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
def info(calibration_file):
    """Print a summary of a calibration file.

    \b
    Example:
      wavemeter info chip.wmcal.json
    """
    calibration = _load(calibration_file)
    document = json.loads(Path(calibration_file).read_text(encoding="utf-8"))
    click.echo(
        f"{calibration_file}: wavemeter {document.get('wavemeter_version')} calibration, "
        f"created {document.get('created_utc')}"
    )
    click.echo("\n".join(_summary_lines(calibration)))
    source = document.get("metadata") or {}
    if source.get("sweep_file"):
        units = ", ".join(sorted({unit or "relative" for unit in source.get("port_units", [])}))
        click.echo(
            f"sweep            {source['sweep_file']} ({source.get('rows')} rows, axis "
            f"{source.get('x_column')} in {source.get('x_unit')}, ports in {units})"
        )


def main(argv=None) -> int:
    """Run the command line; return the exit code (0 ok, 2 user error)."""
    try:
        cli.main(args=argv, prog_name="wavemeter", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        click.echo("error: aborted", err=True)
        return 2
    except click.ClickException as exc:
        click.echo(f"error: {exc.format_message()}", err=True)
        return 2
    except USER_ERRORS as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        click.echo(f"error: {message}", err=True)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
