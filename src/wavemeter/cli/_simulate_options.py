"""The options of ``wavemeter simulate``: their types and declarations.

Each option's name in Python (its ``dest``) is the field of
:class:`~wavemeter.simulation.Scenario` it sets; ``-o``, ``--test-out``, ``--laser-out``,
``--dark-out`` and ``--no-monitor`` are the command's own.
"""

from __future__ import annotations

import math

import click

from ..simulation.scenario_defaults import DEFAULT_THERMAL_RAD_PER_K
from ._common import FSR, out_option, setting
from ._params import (
    BAND,
    FREQUENCY,
    FSRS,
    NOISE_POWER,
    NOISE_POWERS,
    OFFSETS,
    OPTICAL_FREQUENCY,
    POWER,
    TEMPERATURE,
)

__all__ = ["scenario_options", "FiniteFloat", "RampParam", "PLATFORMS", "SPECTRAL_PLATFORMS"]

#: thermal platforms of ``--platform``: the keys of wavemeter.THERMAL_PRESETS
PLATFORMS = ("sin", "soi")
#: laser presets of ``--sweep-axis``: the keys of wavemeter.simulation.SWEEP_PRESETS
SWEEP_AXES = ("tls-spec", "tls-typical", "dfb")
#: spectral platforms of ``--spectral``: the keys of wavemeter.simulation.SPECTRAL_PRESETS
SPECTRAL_PLATFORMS = ("sin",)


class FiniteFloat(click.types.FloatParamType):
    """A finite number (not inf or nan), in ``[low, high)`` when those are given.

    Parameters
    ----------
    low, high : float, optional
        Inclusive lower and exclusive upper bound.
    """

    def __init__(self, low: float | None = None, high: float | None = None):
        self.low = low
        self.high = high

    def convert(self, value, param, ctx):
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value} is not a finite number", param, ctx)
        below = self.low is not None and number < self.low
        above = self.high is not None and number >= self.high
        if below or above:
            if self.low is None:
                allowed = f"< {self.high:g}"
            elif self.high is None:
                allowed = f">= {self.low:g}"
            else:
                allowed = f"in [{self.low:g}, {self.high:g})"
            self.fail(f"{value}: must be {allowed}", param, ctx)
        return number


class RampParam(click.ParamType):
    """A temperature ramp ``A:B``: start and end temperature, each in K or with its unit
    (``290:300``, ``20C:30C``). Converts to a tuple of two floats (K)."""

    name = "A:B"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        parts = str(value).split(":")
        if len(parts) != 2:
            self.fail(f"{value!r} is not a ramp: give start and end as A:B (290:300)", param, ctx)
        return tuple(TEMPERATURE.convert(part, param, ctx) for part in parts)


_OPTIONS = [
    out_option("Sweep file to write (.csv, .tsv, .parquet, .h5, .npz; '-' for stdout)."),
    setting(
        "--ports", 3, click.IntRange(3, 64), "Number of output ports of the MMI (of each stage)."
    ),
    setting("--seed", 1, click.IntRange(0), "Seed of the device impairments and the noise."),
    setting("--samples", 2001, click.IntRange(4), "Readings in the calibration sweep."),
    setting("--span-fsr", 1.0, click.FloatRange(0, min_open=True), "Sweep span in FSRs."),
    setting(
        "--power",
        "1mW",
        POWER,
        "Source power: 1mW, '5e-4 W', 0dBm; a bare number is in W.",
        dest="power_w",
        aliases=("--power-w",),
    ),
    setting(
        "--noise",
        "5e-7W",
        NOISE_POWER,
        "Detector noise standard deviation per reading: 5e-7W, 0.5uW; a bare number is in W.",
        dest="noise_w",
        aliases=("--noise-w",),
    ),
    setting(
        "--fsr",
        "50GHz",
        FSR,
        "Design FSR: 50GHz, '49.69 GHz'; a bare number is in Hz (the device's FSR differs by "
        "Table 1's 5 % delay spread).",
        dest="fsr_hz",
    ),
    click.option(
        "--cascade",
        "cascade_fsrs_hz",
        type=FSRS,
        metavar="FSR,FSR,..",
        help="Simulate a cascade of Table 1 stages of these design FSRs, coarsest first, fed by "
        "one source through an equal splitter (5THz,500GHz,50GHz): port columns p11, p12, .. "
        "(stage, port) over --band.",
    ),
    click.option(
        "--band",
        "band_hz",
        type=BAND,
        metavar="LOW:HIGH",
        help="Band a --cascade sweep covers, evenly, ends included: 191THz:195.4THz, "
        "1534nm:1570nm (default 191THz:195.4THz, the C band); the stages are centred in it.",
    ),
    click.option(
        "--test",
        default=0,
        type=click.IntRange(0),
        help="Also write this many readings at random frequencies with a truth column.",
    ),
    click.option(
        "--test-out",
        type=click.Path(dir_okay=False, allow_dash=True),
        help="Test file (default: OUT with '-test' before the extension).",
    ),
    click.option(
        "--dark",
        default=0,
        type=click.IntRange(0),
        metavar="N",
        help="Also write N readings with the source off (dark offset and noise), for "
        "`wavemeter calibrate --dark`.",
    ),
    click.option(
        "--dark-out",
        type=click.Path(dir_okay=False, allow_dash=True),
        help="Dark file (default: OUT with '-dark' before the extension).",
    ),
    setting(
        "--write-axis-unit",
        "Hz",
        None,
        "Unit the axis column is written in: Hz..THz gives frequency_<unit>, nm/um/m "
        "wavelength_<unit>.",
        dest="x_unit",
        aliases=("--x-unit",),
        metavar="UNIT",
    ),
    setting(
        "--write-power-unit",
        "W",
        None,
        "Unit the port columns are written in: W, mW, uW, nW or dBm (a reading <= 0 W is "
        "-200 dBm).",
        dest="power_unit",
        aliases=("--power-unit",),
        metavar="UNIT",
    ),
    setting(
        "--power-fluctuation",
        0.0,
        click.FloatRange(0, 0.3),
        "Relative std of the source power per reading; > 0 adds a monitor column.",
    ),
    click.option(
        "--dark-offset",
        "dark_offset_w",
        type=OFFSETS,
        help="Fault: detector dark/ADC offset added to every reading, one for all ports or one "
        "per port: 2uW, '1e-7,0,-5e-8'; a bare number is in W. Every file.",
    ),
    click.option(
        "--port-noise",
        "port_noise_w",
        type=NOISE_POWERS,
        help="Fault: detector noise standard deviation of each port, replacing --noise (give "
        "one or the other): '5e-7,2e-6,5e-7'; a bare number is in W. Every file.",
    ),
    click.option(
        "--dispersion",
        "dispersion_s2",
        type=FiniteFloat(),
        metavar="S2",
        help="Fault: group-delay dispersion of the delay imbalance in s^2 (e.g. 1e-26): the group "
        "delay is tau + D 2 pi (f - centre), so the FSR changes across the band. Default 0, or "
        "the --spectral platform's. Every file.",
    ),
    click.option(
        "--spectral",
        type=click.Choice(SPECTRAL_PLATFORMS),
        help="Make the device wide-band: the dispersion of silicon nitride (sin, 4e-28 s^2) and "
        "random slopes of the coupler entries (sigma 1 %/THz, 0.2 %/THz symmetry breaking) and "
        "responsivities (0.5 %/THz), drawn from --seed. Every file.",
    ),
    click.option(
        "--coupler-slope",
        "coupler_slope_sigma_per_thz",
        type=FiniteFloat(0.0),
        metavar="PER_THZ",
        help="Sigma of the random relative slope per THz of the output-coupler entries (real "
        "and imaginary parts), shared by the entries the MMI symmetry makes equal, drawn from "
        "--seed: 0.01 is 1 %/THz. Replaces --spectral's; its symmetry-breaking part stays the "
        "platform's (none without --spectral).",
    ),
    click.option(
        "--responsivity-slope",
        "responsivity_slope_sigma_per_thz",
        type=FiniteFloat(0.0),
        metavar="PER_THZ",
        help="Sigma of the random relative slope per THz of each port's responsivity, drawn from "
        "--seed: 0.005 is 0.5 %/THz. Replaces --spectral's.",
    ),
    setting(
        "--power-drift",
        0.0,
        FiniteFloat(0.0, 1.0),
        "Fault: slow drift of the source power over the calibration sweep, peak relative "
        "excursion in [0, 1) (0.05 is +-5 %); adds a monitor column that records the drifting "
        "power. Sweep only.",
        metavar="FRACTION",
    ),
    setting(
        "--thermal-drift",
        0.0,
        FiniteFloat(),
        "Fault: chip temperature rise (K) over the calibration sweep, a linear ramp from 0 "
        f"moving the bias phase at the device's thermal coefficient ({DEFAULT_THERMAL_RAD_PER_K:g}"
        " rad/K for a Table 1 device, which has none); no temperature column. Sweep only.",
        dest="thermal_drift_k",
        metavar="K",
    ),
    click.option(
        "--platform",
        type=click.Choice(PLATFORMS),
        help="Make the device thermal: the fringe shift and delay rate of silicon nitride (sin, "
        "2.6 GHz/K) or silicon on insulator (soi, 10 GHz/K); the files get a temperature_k column.",
    ),
    click.option(
        "--temperature-k",
        type=TEMPERATURE,
        metavar="T",
        help="Chip temperature of the whole recording (--platform): 293.15 (K), 293.15K, 20C. "
        "Default: the device's reference temperature, 293.15 K.",
    ),
    click.option(
        "--ramp-k",
        type=RampParam(),
        metavar="A:B",
        help="Chip temperature ramping linearly from A to B over the recording (--platform), "
        "e.g. 290:300; the test readings at temperatures uniform over the ramp.",
    ),
    setting(
        "--repeat",
        1,
        click.IntRange(1),
        "Record the sweep this many times in a row (a recording of --repeat x --samples rows; "
        "with --ramp-k the sweeps see different temperatures).",
    ),
    click.option(
        "--no-monitor",
        is_flag=True,
        help="Write no monitor column even when the source power varies (to see a drift "
        "without the monitor remedy).",
    ),
    click.option(
        "--laser",
        default=0,
        type=click.IntRange(0),
        metavar="N",
        help="Also write N readings of a laser with frequency noise at --laser-rate, with a "
        "time_s column, for `wavemeter noise` (with the calibration of the sweep).",
    ),
    click.option(
        "--laser-out",
        type=click.Path(dir_okay=False, allow_dash=True),
        help="Laser file (default: OUT with '-laser' before the extension).",
    ),
    setting(
        "--laser-rate",
        "10MHz",
        FREQUENCY,
        "Sample rate of the laser readings: 10MHz, 250kHz; a bare number is in Hz.",
        dest="laser_rate_hz",
    ),
    click.option(
        "--laser-frequency",
        "laser_center_hz",
        type=OPTICAL_FREQUENCY,
        help="Laser frequency at the first reading: 193.4THz, 1550nm (default: the device's "
        "centre, the middle of the sweep).",
    ),
    setting(
        "--white-fm",
        0.0,
        FiniteFloat(0.0),
        "The laser's white FM level h0 in Hz^2/Hz: its Lorentzian linewidth is pi h0 (1.6e8 is "
        "500 MHz).",
        dest="white_fm_hz2_per_hz",
        metavar="HZ2_PER_HZ",
    ),
    setting(
        "--flicker-fm",
        0.0,
        FiniteFloat(0.0),
        "The laser's flicker FM level h_-1 in Hz^2 (a PSD h_-1 / f).",
        dest="flicker_fm_hz2",
        metavar="HZ2",
    ),
    setting(
        "--random-walk-fm",
        0.0,
        FiniteFloat(0.0),
        "The laser's random-walk FM level h_-2 in Hz^2/s (a PSD h_-2 / f^2).",
        dest="random_walk_fm_hz2_per_s",
        metavar="HZ2_PER_S",
    ),
    setting(
        "--laser-drift",
        0.0,
        FiniteFloat(),
        "The laser's linear frequency drift in Hz/s.",
        dest="laser_drift_hz_per_s",
        metavar="HZ_PER_S",
    ),
    click.option(
        "--sweep-axis",
        type=click.Choice(SWEEP_AXES),
        help="The sweep's axis column is what a laser records: tls-spec (a tunable laser at "
        "its +-10 pm specification), tls-typical (3.6 pm), dfb (tuned by current, nominal "
        "coefficient only); the truth goes to simulated_true_frequency_hz (evaluation only).",
    ),
    click.option(
        "--reference-cell",
        metavar="NAME|FILE",
        help="Record a reference gas cell beside the ports (cell_transmission column): a "
        "simulated band (hcn-like: NOT real HCN lines; its table is written to OUT with "
        "-lines.csv for calibrate --lines) or your line table file.",
    ),
]


def scenario_options(command):
    """Every option of ``simulate`` but the shared ``--format``, ``--force``, ``--quiet``,
    in the order ``--help`` shows them."""
    for option in reversed(_OPTIONS):
        command = option(command)
    return command
