"""`wavemeter simulate`: a sweep of a simulated Table 1 device, written to a file."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from ..exceptions import InputError
from ..io._reader import SENTINEL_DBM, table_format, write_table
from ..progress import chunked
from ..units import canonical_unit, hz_to_axis, w_to_power
from ._common import (
    FORMAT,
    FREQUENCY,
    QUIET,
    out_option,
    say,
    setting,
)


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


@click.command()
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
        say(options["quiet"], f"wrote {path} ({rows} rows: {', '.join(columns)})")
        codes = sum(int(np.count_nonzero(values == SENTINEL_DBM)) for values in columns.values())
        if options["power_unit"] == "dBm" and codes:
            say(
                options["quiet"],
                f"note: {codes} reading(s) at or below 0 W (noise at a fringe null) are written "
                f"as the {SENTINEL_DBM:g} dBm no-reading code; read {path} with --drop-invalid, "
                "or simulate with a lower --noise-w",
            )
    say(
        options["quiet"],
        f"device: Table 1, {device.ports} ports, seed {options['seed']}, true FSR "
        f"{device.true_fsr_hz / 1e9:.6f} GHz, centre {device.center_hz / 1e12:.6f} THz",
    )


command = simulate
