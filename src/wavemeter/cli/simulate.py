"""`wavemeter simulate`: a sweep of a simulated Table 1 device, written to a file."""

from __future__ import annotations

import os
from pathlib import Path

import click
import numpy as np

from ..exceptions import InputError
from ..io import SENTINEL_DBM, write_table
from ..progress import busy, chunked
from ..units import canonical_unit, hz_to_axis, w_to_power
from ._common import (
    FORCE,
    FORMAT,
    FSR,
    QUIET,
    fsr_text,
    note,
    optical_text,
    out_option,
    output_format,
    printable,
    say,
    setting,
)
from ._params import NOISE_POWER, POWER
from ._streams import is_stdio


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


def _readings(device, frequency_hz, options, rng, description) -> dict[str, np.ndarray]:
    """Port columns (and, with a power fluctuation, a monitor) for frequencies (Hz)."""
    samples = frequency_hz.size
    power = np.full(samples, options["power_w"])
    if options["power_fluctuation"] > 0:
        power = power * (1 + options["power_fluctuation"] * rng.standard_normal(samples))
    powers = np.empty((samples, device.ports))
    for rows in chunked(samples, description, quiet=options["quiet"]):
        powers[rows] = device.powers(frequency_hz[rows], power[rows], options["noise_w"], rng)
    columns = _power_columns(powers, options["power_unit"])
    if options["power_fluctuation"] > 0:
        unit = options["power_unit"]
        columns[f"monitor_{_suffix(unit)}"] = w_to_power(device.monitor(power), unit)
    return columns


def _targets(out_path: str, test_samples: int, test_out: str | None) -> list[str]:
    """The files to write: the sweep, and with ``--test`` the test file (distinct)."""
    if not test_samples:
        return [out_path]
    if test_out is None:
        if is_stdio(out_path):
            raise InputError("with -o - (stdout) and --test, name the test file with --test-out")
        test_out = str(Path(out_path).with_stem(f"{Path(out_path).stem}-test"))
    same = is_stdio(out_path) and is_stdio(test_out)
    if not same and not is_stdio(out_path) and not is_stdio(test_out):
        same = os.path.realpath(out_path) == os.path.realpath(test_out)
    if same:
        raise InputError(f"--test-out {test_out} is the sweep file too: give two different files")
    return [out_path, test_out]


@click.command()
@out_option("Sweep file to write (.csv, .tsv, .parquet, .h5, .npz; '-' for stdout).")
@setting("--ports", 3, click.IntRange(3, 64), "Number of output ports of the MMI.")
@setting("--seed", 1, int, "Seed of the device impairments and the noise.")
@setting("--samples", 2001, click.IntRange(4), "Readings in the calibration sweep.")
@setting("--span-fsr", 1.0, click.FloatRange(0, min_open=True), "Sweep span in FSRs.")
@setting(
    "--power",
    "1mW",
    POWER,
    "Source power: 1mW, '5e-4 W', 0dBm; a bare number is in W.",
    dest="power_w",
    aliases=("--power-w",),
)
@setting(
    "--noise",
    "5e-7W",
    NOISE_POWER,
    "Detector noise standard deviation per reading: 5e-7W, 0.5uW; a bare number is in W.",
    dest="noise_w",
    aliases=("--noise-w",),
)
@setting(
    "--fsr",
    "50GHz",
    FSR,
    "Design FSR: 50GHz, '49.69 GHz'; a bare number is in Hz (the device's FSR differs by "
    "Table 1's 5 % delay spread).",
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
    type=click.Path(dir_okay=False, allow_dash=True),
    help="Test file (default: OUT with '-test' before the extension).",
)
@setting(
    "--write-axis-unit",
    "Hz",
    None,
    "Unit the axis column is written in: Hz..THz gives frequency_<unit>, nm/um/m "
    "wavelength_<unit>.",
    dest="x_unit",
    aliases=("--x-unit",),
    metavar="UNIT",
)
@setting(
    "--write-power-unit",
    "W",
    None,
    "Unit the port columns are written in: W, mW, uW, nW or dBm (a reading <= 0 W is -200 dBm).",
    dest="power_unit",
    aliases=("--power-unit",),
    metavar="UNIT",
)
@setting(
    "--power-fluctuation",
    0.0,
    click.FloatRange(0, 0.3),
    "Relative std of the source power per reading; > 0 adds a monitor column.",
)
@FORMAT
@FORCE
@QUIET
def simulate(out_path, test_samples, test_out, force, **options):
    """Simulate a sweep of a Table 1 device (paper Section III) and write it to a file.

    Powers take a unit (1mW, 5e-7W, -30dBm) and frequencies too (50GHz); bare numbers are
    SI (W, Hz). Both files are checked before anything is simulated; an existing file is
    replaced only with --force.

    \b
    Example:
      wavemeter simulate -o sweep.csv --ports 3 --seed 1 --test 20000
      wavemeter simulate -o lab.csv --write-axis-unit nm --write-power-unit dBm --noise 20nW
    """
    from ..simulation.interferometer import Interferometer

    quiet = options["quiet"]
    x_unit = canonical_unit(options["x_unit"], "axis", "--write-axis-unit")
    power_unit = canonical_unit(options["power_unit"], "power", "--write-power-unit")
    if power_unit == "V":
        raise InputError("--write-power-unit V is not a simulated output; use W, mW, uW, nW or dBm")
    options["power_unit"] = power_unit
    targets = _targets(out_path, test_samples, test_out)
    formats = [output_format(path, options["file_format"], force=force) for path in targets]
    messages_to_stderr = any(is_stdio(path) for path in targets)
    device = Interferometer.table1(options["ports"], seed=options["seed"], fsr_hz=options["fsr"])
    rng = np.random.default_rng(options["seed"])  # as the demo: the same seed, the same data
    sweep_hz = device.sweep_hz(options["samples"], options["span_fsr"])
    frequencies = [(_axis_column(x_unit), sweep_hz)]
    if test_samples:
        low, high = sweep_hz[0], sweep_hz[-1]
        frequencies.append((_axis_column(x_unit, "true_"), rng.uniform(low, high, test_samples)))
    tables = [  # everything is simulated before anything is written
        {
            axis: hz_to_axis(frequency, x_unit),
            **_readings(device, frequency, options, rng, printable(f"simulating {path}")),
        }
        for path, (axis, frequency) in zip(targets, frequencies, strict=True)
    ]
    for path, file_format, columns in zip(targets, formats, tables, strict=True):
        with busy(printable(f"writing {path}"), quiet=quiet):
            write_table(path, columns, file_format)
        rows = len(next(iter(columns.values())))
        written = "stdout" if is_stdio(path) else path
        say(quiet, f"wrote {written} ({rows} rows: {', '.join(columns)})", err=messages_to_stderr)
        codes = sum(int(np.count_nonzero(values == SENTINEL_DBM)) for values in columns.values())
        if power_unit == "dBm" and codes:
            note(
                quiet,
                f"{codes} reading(s) at or below 0 W (noise at a fringe null) are written as "
                f"the {SENTINEL_DBM:g} dBm no-reading code; read {path} with --drop-invalid, "
                "or simulate with a lower --noise",
            )
    say(
        quiet,
        f"device: Table 1, {device.ports} ports, seed {options['seed']}, true FSR "
        f"{fsr_text(device.true_fsr_hz)}, centre {optical_text(device.center_hz)}",
        err=messages_to_stderr,
    )


command = simulate
