"""`wavemeter simulate`: a sweep of a simulated Table 1 device, written to a file.

Hardware faults can be added: detector dark offsets, unequal detector noise and group-delay
dispersion are properties of the device and reach every file; a source-power drift and a
thermal drift happen during the calibration sweep only.

A wide-band device (``--spectral sin``: the dispersion of silicon nitride, and output-coupler
entries and responsivities that change slowly with frequency) makes a C-band sweep
realistic (``--span-fsr 88``); ``--dispersion``, ``--coupler-slope`` and
``--responsivity-slope`` replace the preset's values or set them alone. The slopes are
drawn from a stream of the seed of their own, so the device's Table 1 impairments and the
noise stay those of the seed.

A thermal device (``--platform sin|soi``: the fringe shift and delay rate of silicon nitride
or silicon on insulator) is recorded at a chip temperature (``--temperature-k``, default
the device's reference 293.15 K) or during a linear ramp (``--ramp-k A:B`` over the whole
recording, with ``--repeat`` sweeps in a row), and the files get a ``temperature_k``
column. Runs at different temperatures simulate the same device (same ``--seed``) with
noise of their own: the noise is drawn from a stream of the seed and the temperatures.

A cascade (``--cascade 5THz,500GHz,50GHz``: Table 1 stages of decreasing FSR fed by one
source through an equal splitter, :class:`~wavemeter.simulation.CascadeInterferometer`) is
swept over ``--band LOW:HIGH`` (default the C band, 191-195.4 THz), centred in it; its port
columns are named ``p<stage><port>`` (``p11, p12, p13, p21, ...``, the port zero-padded past
9 ports), which the readers find in that order. ``--ports`` is each stage's port count and
``--power`` the source power before the split.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import click
import numpy as np
from click.core import ParameterSource

from ..exceptions import InputError
from ..io import SENTINEL_DBM, write_table
from ..progress import busy, chunked
from ..units import canonical_unit, hz_to_axis, w_to_power
from ._common import (
    FORCE,
    FORMAT,
    FSR,
    QUIET,
    frequency_text,
    fsr_text,
    note,
    optical_text,
    out_option,
    output_format,
    printable,
    say,
    setting,
)
from ._params import BAND, FSRS, NOISE_POWER, NOISE_POWERS, OFFSETS, POWER, TEMPERATURE
from ._streams import is_stdio

#: bias phase change per kelvin of ``--thermal-drift`` for a device without a thermal
#: coefficient (a Table 1 device has none)
DEFAULT_THERMAL_RAD_PER_K = 1.0
#: the power drift is drawn from its own stream of the seed, so that adding it leaves the
#: noise of the readings as it was
_DRIFT_STREAM = 1
#: a recording at a given temperature (or ramp) draws its noise from this stream of the seed
#: and the temperatures in mK, so that runs at different temperatures have their own noise
_TEMPERATURE_STREAM = 2
#: the spectral slopes are drawn from this stream of the seed: the seed itself would draw
#: them from the numbers of the Table 1 spread, in proportion to it
_SPECTRAL_STREAM = 3
#: thermal platforms of ``--platform``: the keys of wavemeter.THERMAL_PRESETS
PLATFORMS = ("sin", "soi")
#: spectral platforms of ``--spectral``: the keys of wavemeter.simulation.SPECTRAL_PRESETS
SPECTRAL_PLATFORMS = ("sin",)
#: the band a cascade is swept over when --band is not given: the C band (Hz)
DEFAULT_CASCADE_BAND_HZ = (191.0e12, 195.4e12)
#: options a cascade is not simulated with: option dest -> why, as the message says it
_NOT_FOR_CASCADE = {
    "fsr": "the stages' FSRs are --cascade's",
    "span_fsr": "a cascade's sweep covers --band",
    "dark_offset_w": "the detector faults are simulated for a single device",
    "dispersion_s2": "--spectral sin gives every stage the dispersion of its delay",
    "coupler_slope": "--spectral sin gives every stage its spectral slopes",
    "responsivity_slope": "--spectral sin gives every stage its spectral slopes",
    "thermal_drift_k": "the thermal faults are simulated for a single device",
    "platform": "the thermal devices are single devices",
    "temperature_k": "the thermal devices are single devices",
    "ramp_k": "the thermal devices are single devices",
}
#: options that set a field of the spectral preset: option dest -> SpectralPreset field
_SPECTRAL_OPTIONS = {
    "dispersion_s2": "dispersion_s2",
    "coupler_slope": "coupler_slope_sigma_per_thz",
    "responsivity_slope": "responsivity_slope_sigma_per_thz",
}


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


def _suffix(unit: str) -> str:
    """Unit suffix of a column name: ``frequency_hz``, ``p1_w``, ``freq_THz``, ``p1_dBm``."""
    return unit.lower() if unit in ("Hz", "W") else unit


def _axis_column(unit: str, prefix: str = "") -> str:
    word = "frequency" if unit.endswith("Hz") else "wavelength"
    return f"{prefix}{word}_{_suffix(unit)}"


def _is_cascade(device) -> bool:
    return hasattr(device, "stages")


def _port_names(device) -> list[str]:
    """Names of the port columns without their unit: ``p1, p2, ...`` for a single device,
    ``p11, p12, ..., p21, ...`` (stage, then port, zero-padded to the widest port number)
    for a cascade, so that the readers find them in reading order and the stage shows."""
    if not _is_cascade(device):
        return [f"p{k + 1}" for k in range(device.ports)]
    width = len(str(max(stage.ports for stage in device.stages)))
    return [
        f"p{index + 1}{port + 1:0{width}d}"
        for index, stage in enumerate(device.stages)
        for port in range(stage.ports)
    ]


def _power_columns(powers_w: np.ndarray, unit: str, names: list[str]) -> dict[str, np.ndarray]:
    """Port columns ``<name>_<unit>``; in dBm a reading <= 0 W becomes the -200 dBm code."""
    values = w_to_power(powers_w, unit)
    if unit == "dBm":
        values = np.where(np.isfinite(values), values, SENTINEL_DBM)
    return {f"{name}_{_suffix(unit)}": values[:, k] for k, name in enumerate(names)}


def _monitor_w(device, power_w: np.ndarray) -> np.ndarray:
    """The monitor reading (W) of the source power: a cascade's is its first stage's tap."""
    return (device.stages[0] if _is_cascade(device) else device).monitor(power_w)


def _readings(
    device,
    frequency_hz,
    options,
    rng,
    description,
    power_factor=None,
    bias_drift_rad=None,
    temperature_k=None,
) -> dict[str, np.ndarray]:
    """Port columns (and, if ``options["monitor"]``, a monitor; with ``temperature_k`` a
    ``temperature_k`` column) for frequencies (Hz).

    ``power_factor`` multiplies the source power and ``bias_drift_rad`` adds to the bias
    phase of each reading; ``temperature_k`` is the chip temperature of each (K) (shape
    (N,) each; None: no drift, the device's reference temperature).
    """
    samples = frequency_hz.size
    power = np.full(samples, options["power_w"])
    if power_factor is not None:
        power = power * power_factor
    if options["power_fluctuation"] > 0:
        power = power * (1 + options["power_fluctuation"] * rng.standard_normal(samples))
    powers = np.empty((samples, device.ports))
    for rows in chunked(samples, description, quiet=options["quiet"]):
        extra = {}  # a cascade has neither
        if bias_drift_rad is not None:
            extra["bias_drift_rad"] = bias_drift_rad[rows]
        if temperature_k is not None:
            extra["temperature_k"] = temperature_k[rows]
        powers[rows] = device.powers(
            frequency_hz[rows], power[rows], options["noise_w"], rng, **extra
        )
    columns = _power_columns(powers, options["power_unit"], _port_names(device))
    if options["monitor"]:
        unit = options["power_unit"]
        columns[f"monitor_{_suffix(unit)}"] = w_to_power(_monitor_w(device, power), unit)
    if temperature_k is not None:
        columns["temperature_k"] = temperature_k
    return columns


def _per_port(values_w: tuple, ports: int, option: str, *, single: bool) -> np.ndarray:
    """A per-port array (W) from an option's list: ``ports`` values, or one for all if
    ``single``."""
    values_w = np.asarray(values_w)
    if single and values_w.size == 1:
        return np.full(ports, values_w[0])
    if values_w.size != ports:
        allowed = f"one for all ports or {ports}" if single else f"{ports}, one per port"
        raise InputError(f"{option} has {values_w.size} value(s) for {ports} ports: give {allowed}")
    return values_w


def _noise_w(options, ports: int):
    """Detector noise std (W): ``--noise`` for every port, or ``--port-noise`` per port."""
    if options["port_noise_w"] is None:
        return options["noise_w"]
    if click.get_current_context().get_parameter_source("noise_w") != ParameterSource.DEFAULT:
        raise InputError("give --noise (every port) or --port-noise (each port), not both")
    return _per_port(options["port_noise_w"], ports, "--port-noise", single=False)


def _faulty(device, options):
    """The device with the detector fault it carries into every file: the dark offset."""
    offset_w = options["dark_offset_w"]
    if offset_w is not None:
        offset_w = _per_port(offset_w, device.ports, "--dark-offset", single=True)
    return dataclasses.replace(device, dark_offset_w=offset_w)


def _spectral(device, options):
    """The device with the dispersion and spectral slopes of ``--spectral``, each replaced
    by ``--dispersion``, ``--coupler-slope`` or ``--responsivity-slope`` when given.

    Returns
    -------
    device : Interferometer
    preset : SpectralPreset or None
        What the slopes were drawn with (from a stream of the seed); None when neither
        ``--spectral`` nor a slope option is given (then only ``--dispersion`` applies).
    """
    from ..simulation.spectral_presets import SPECTRAL_PRESETS, SpectralPreset

    given = {
        field: options[name]
        for name, field in _SPECTRAL_OPTIONS.items()
        if options[name] is not None
    }
    platform = options["spectral"]
    if platform is None and set(given) <= {"dispersion_s2"}:
        return dataclasses.replace(device, dispersion_s2=given.get("dispersion_s2", 0.0)), None
    preset = SPECTRAL_PRESETS[platform] if platform else SpectralPreset(0.0, 0.0, 0.0, 0.0)
    preset = dataclasses.replace(preset, **given)
    rng = np.random.default_rng([options["seed"], _SPECTRAL_STREAM])
    return device.with_spectral(preset, seed=rng), preset


def _spectral_text(device, preset, sweep_hz: np.ndarray, platform: str | None) -> str:
    """The ``spectral:`` summary line: dispersion, slope sigmas, local FSR over the sweep."""
    parts = [platform or "custom", f"dispersion {device.dispersion_s2:.3g} s^2"]
    if preset is not None:
        parts.append(
            f"slope sigmas: coupler {preset.coupler_slope_sigma_per_thz:.3g} /THz (symmetry "
            f"breaking {preset.coupler_breaking_sigma_per_thz:.3g} /THz), responsivity "
            f"{preset.responsivity_slope_sigma_per_thz:.3g} /THz"
        )
    local_hz = device.local_fsr_hz(np.array([sweep_hz.min(), sweep_hz.max()]))
    parts.append(
        f"local FSR {fsr_text(local_hz[0])} at the sweep's low end, {fsr_text(local_hz[1])} "
        "at its high end"
    )
    return "spectral: " + ", ".join(parts)


def _sweep_drift(device, samples: int, options) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The calibration sweep's source-power factor and bias drift (rad), None when off."""
    from ..simulation.drift import slow_power_drift, thermal_ramp_rad

    power_factor = bias_drift_rad = None
    if options["power_drift"] > 0:
        drift_rng = np.random.default_rng([options["seed"], _DRIFT_STREAM])
        power_factor = slow_power_drift(samples, options["power_drift"], drift_rng)
    if options["thermal_drift_k"] != 0:
        rad_per_k = device.thermal_phase_rad_per_k or DEFAULT_THERMAL_RAD_PER_K
        bias_drift_rad = thermal_ramp_rad(samples, options["thermal_drift_k"], rad_per_k)
    return power_factor, bias_drift_rad


def _thermal(device, options):
    """The device with the thermal coefficients of ``--platform``; refuses a temperature
    for a device without them."""
    platform = options["platform"]
    if platform is None:
        for name in ("temperature_k", "ramp_k"):
            if options[name] is not None:
                option = "--" + name.replace("_", "-")
                raise InputError(
                    f"{option} needs a thermal device: add --platform sin or soi (a Table 1 "
                    "device has no thermal coefficients)"
                )
        return device
    if options["temperature_k"] is not None and options["ramp_k"] is not None:
        raise InputError(
            "--temperature-k (one temperature) and --ramp-k (a ramp) both set the chip "
            "temperature; give one of them"
        )
    return device.with_thermal(platform)


def _temperatures_k(device, options, sweep_samples: int, test_samples: int, rng):
    """Chip temperature (K) of the sweep's readings and of the test readings: constant,
    a linear ramp over the sweep (the test readings uniform over it), or None without
    ``--platform``."""
    if options["platform"] is None:
        return None, None
    if options["ramp_k"] is not None:
        start, end = options["ramp_k"]
        sweep = np.linspace(start, end, sweep_samples)
        return sweep, rng.uniform(min(start, end), max(start, end), test_samples)
    temperature = options["temperature_k"]
    if temperature is None:
        temperature = device.reference_temperature_k
    return np.full(sweep_samples, temperature), np.full(test_samples, temperature)


def _noise_rng(options) -> np.random.Generator:
    """The generator of the noise: the seed's (as the demo) at the reference temperature, else
    a stream of the seed and the temperatures given (mK)."""
    given = options["ramp_k"] or (options["temperature_k"],)
    if given == (None,):
        return np.random.default_rng(options["seed"])
    millikelvin = [round(value * 1e3) for value in given]
    return np.random.default_rng([options["seed"], _TEMPERATURE_STREAM, *millikelvin])


def _cascade(options):
    """The cascade of ``--cascade`` over ``--band``, its stages centred in the band;
    refuses the options a cascade is not simulated with and a band its coarsest stage does
    not cover."""
    from ..simulation.cascade import CascadeInterferometer

    context = click.get_current_context()
    for name, reason in _NOT_FOR_CASCADE.items():
        if context.get_parameter_source(name) not in (None, ParameterSource.DEFAULT):
            option = next(param.opts[0] for param in context.command.params if param.name == name)
            raise InputError(
                f"{option} is not simulated for a cascade (--cascade): {reason}; leave it out"
            )
    fsrs = options["cascade"]
    if len(fsrs) < 2 or any(
        fine >= coarse for coarse, fine in zip(fsrs[:-1], fsrs[1:], strict=True)
    ):
        raise InputError(
            f"--cascade {', '.join(frequency_text(value) for value in fsrs)}: a cascade needs "
            "two or more stages of decreasing FSR, coarsest first (e.g. 5THz,500GHz,50GHz)"
        )
    low, high = options["band"] or DEFAULT_CASCADE_BAND_HZ
    device = CascadeInterferometer.table1(
        fsrs,
        ports=options["ports"],
        seed=options["seed"],
        center_hz=(low + high) / 2,
        spectral=options["spectral"],
    )
    coarsest = device.true_fsrs_hz[0]
    if coarsest <= high - low:
        raise InputError(
            f"the coarsest stage's FSR ({frequency_text(coarsest)} as drawn, design "
            f"{frequency_text(fsrs[0])}) does not exceed the band {frequency_text(low)} to "
            f"{frequency_text(high)} ({frequency_text(high - low)}): its phase repeats within "
            "the band and no cascade can read it; give a narrower --band or a coarser first "
            "stage"
        )
    return device


def _cascade_text(device, band_hz, seed: int, spectral: str | None) -> list[str]:
    """The ``device:`` line of a cascade (stages, columns, FSRs, band) and, with
    ``spectral``, the ``spectral:`` line (each stage's dispersion, the finest stage's
    local FSR at the band's ends)."""
    names = _port_names(device)
    columns = ", ".join(f"{names[block[0]]}-{names[block[-1]]}" for block in device.stage_ports)
    low, high = band_hz
    lines = [
        f"device: cascade of {len(device.stages)} Table 1 stages, "
        f"{device.stages[0].ports} ports each (columns {columns}), seed {seed}, true FSRs "
        f"{', '.join(frequency_text(value) for value in device.true_fsrs_hz)}, band "
        f"{optical_text(low)} to {optical_text(high)}"
    ]
    if spectral is not None:
        local_hz = device.stages[-1].local_fsr_hz(np.array([low, high]))
        dispersions = ", ".join(f"{stage.dispersion_s2:.3g}" for stage in device.stages)
        lines.append(
            f"spectral: {spectral}, dispersion {dispersions} s^2 (stage by stage), the finest "
            f"stage's local FSR {fsr_text(local_hz[0])} at the band's low end, "
            f"{fsr_text(local_hz[1])} at its high end"
        )
    return lines


def _temperature_text(temperature_k: np.ndarray) -> str:
    start, end = temperature_k[0], temperature_k[-1]
    return f"{start:.6g} K" if start == end else f"{start:.6g} to {end:.6g} K"


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
@setting("--ports", 3, click.IntRange(3, 64), "Number of output ports of the MMI (of each stage).")
@setting("--seed", 1, click.IntRange(0), "Seed of the device impairments and the noise.")
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
    "--cascade",
    type=FSRS,
    metavar="FSR,FSR,..",
    help="Simulate a cascade of Table 1 stages of these design FSRs, coarsest first, fed by "
    "one source through an equal splitter (5THz,500GHz,50GHz): port columns p11, p12, .. "
    "(stage, port) over --band.",
)
@click.option(
    "--band",
    type=BAND,
    metavar="LOW:HIGH",
    help="Band a --cascade sweep covers, evenly, ends included: 191THz:195.4THz, "
    "1534nm:1570nm (default 191THz:195.4THz, the C band); the stages are centred in it.",
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
@click.option(
    "--dark-offset",
    "dark_offset_w",
    type=OFFSETS,
    help="Fault: detector dark/ADC offset added to every reading, one for all ports or one "
    "per port: 2uW, '1e-7,0,-5e-8'; a bare number is in W. Sweep and test file.",
)
@click.option(
    "--port-noise",
    "port_noise_w",
    type=NOISE_POWERS,
    help="Fault: detector noise standard deviation of each port, replacing --noise (give "
    "one or the other): '5e-7,2e-6,5e-7'; a bare number is in W. Sweep and test file.",
)
@click.option(
    "--dispersion",
    "dispersion_s2",
    type=FiniteFloat(),
    metavar="S2",
    help="Fault: group-delay dispersion of the delay imbalance in s^2 (e.g. 1e-26): the group "
    "delay is tau + D 2 pi (f - centre), so the FSR changes across the band. Default 0, or "
    "the --spectral platform's. Sweep and test file.",
)
@click.option(
    "--spectral",
    type=click.Choice(SPECTRAL_PLATFORMS),
    help="Make the device wide-band: the dispersion of silicon nitride (sin, 4e-28 s^2) and "
    "random slopes of the coupler entries (sigma 1 %/THz, 0.2 %/THz symmetry breaking) and "
    "responsivities (0.5 %/THz), drawn from --seed. Sweep and test file.",
)
@click.option(
    "--coupler-slope",
    type=FiniteFloat(0.0),
    metavar="PER_THZ",
    help="Sigma of the random relative slope per THz of the output-coupler entries (real "
    "and imaginary parts), shared by the entries the MMI symmetry makes equal, drawn from "
    "--seed: 0.01 is 1 %/THz. Replaces --spectral's; its symmetry-breaking part stays the "
    "platform's (none without --spectral).",
)
@click.option(
    "--responsivity-slope",
    type=FiniteFloat(0.0),
    metavar="PER_THZ",
    help="Sigma of the random relative slope per THz of each port's responsivity, drawn from "
    "--seed: 0.005 is 0.5 %/THz. Replaces --spectral's.",
)
@setting(
    "--power-drift",
    0.0,
    FiniteFloat(0.0, 1.0),
    "Fault: slow drift of the source power over the calibration sweep, peak relative "
    "excursion in [0, 1) (0.05 is +-5 %); adds a monitor column that records the drifting power. "
    "Sweep only.",
    metavar="FRACTION",
)
@setting(
    "--thermal-drift",
    0.0,
    FiniteFloat(),
    "Fault: chip temperature rise (K) over the calibration sweep, a linear ramp from 0 "
    f"moving the bias phase at the device's thermal coefficient ({DEFAULT_THERMAL_RAD_PER_K:g}"
    " rad/K for a Table 1 device, which has none); no temperature column. Sweep only.",
    dest="thermal_drift_k",
    metavar="K",
)
@click.option(
    "--platform",
    type=click.Choice(PLATFORMS),
    help="Make the device thermal: the fringe shift and delay rate of silicon nitride (sin, "
    "2.6 GHz/K) or silicon on insulator (soi, 10 GHz/K); the files get a temperature_k column.",
)
@click.option(
    "--temperature-k",
    type=TEMPERATURE,
    metavar="T",
    help="Chip temperature of the whole recording (--platform): 293.15 (K), 293.15K, 20C. "
    "Default: the device's reference temperature, 293.15 K.",
)
@click.option(
    "--ramp-k",
    type=RampParam(),
    metavar="A:B",
    help="Chip temperature ramping linearly from A to B over the recording (--platform), "
    "e.g. 290:300; the test readings at temperatures uniform over the ramp.",
)
@setting(
    "--repeat",
    1,
    click.IntRange(1),
    "Record the sweep this many times in a row (a recording of --repeat x --samples rows; "
    "with --ramp-k the sweeps see different temperatures).",
)
@click.option(
    "--no-monitor",
    is_flag=True,
    help="Write no monitor column even when the source power varies (to see a drift "
    "without the monitor remedy).",
)
@FORMAT
@FORCE
@QUIET
def simulate(out_path, test_samples, test_out, force, **options):
    """Simulate a sweep of a Table 1 device (paper Section III) and write it to a file.

    Powers take a unit (1mW, 5e-7W, -30dBm) and frequencies too (50GHz); bare numbers are
    SI (W, Hz). Both files are checked before anything is simulated; an existing file is
    replaced only with --force.

    Fault options (--dark-offset, --port-noise, --dispersion, --power-drift, --thermal-drift)
    model real hardware. The detectors and the chip's dispersion are the device's: they
    reach the --test file too. The drifts happen during the calibration sweep: the test
    file has none. The power drift has a random stream of its own, so the noise is the
    same as without it. A monitor column is written when the source power varies
    (--power-fluctuation or --power-drift) and records the true source power, in both
    files unless --no-monitor.

    A thermal device (--platform) is recorded at --temperature-k, or during --ramp-k
    (with --repeat sweeps in a row, so that temperature and frequency do not change
    together); both files get a temperature_k column. Runs at several temperatures with
    one --seed simulate one device, each with noise of its own.

    A wide-band device (--spectral sin, or --coupler-slope and --responsivity-slope alone)
    has an output coupler and receivers that change slowly with frequency, drawn from
    --seed, and the platform's dispersion; a C-band sweep is --span-fsr 88.

    A cascade (--cascade 5THz,500GHz,50GHz) is Table 1 stages of decreasing FSR with
    --ports ports each, fed by one source (--power, split equally), swept evenly over
    --band (default the C band, 191-195.4 THz); the test readings are uniform over the
    band. Its port columns p11, p12, .., p21, .. name stage and port. With --spectral sin
    every stage gets the platform's slopes and the dispersion of its delay. The single
    device's FSR, span, detector and thermal faults are not simulated for a cascade.

    \b
    Example:
      wavemeter simulate -o sweep.csv --ports 3 --seed 1 --test 20000
      wavemeter simulate -o lab.csv --write-axis-unit nm --write-power-unit dBm --noise 20nW
      wavemeter simulate -o faulty.csv --dark-offset 2uW --power-drift 0.05 --test 2000
      wavemeter simulate -o s290.csv --platform sin --temperature-k 290
      wavemeter simulate -o ramp.csv --platform sin --ramp-k 290:300 --repeat 5
      wavemeter simulate -o band.csv --spectral sin --span-fsr 88 --samples 176000
      wavemeter simulate -o cband.csv --cascade 5THz,500GHz,50GHz --spectral sin \\
          --samples 20000 --test 100000
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
    cascade = options["cascade"] is not None
    if cascade:
        device, spectral_preset = _cascade(options), None
        band = options["band"] or DEFAULT_CASCADE_BAND_HZ
        sweep_hz = np.linspace(*band, options["samples"])
    else:
        if options["band"] is not None:
            raise InputError(
                "--band is the band of a cascade (--cascade); a single device's sweep is "
                "--span-fsr FSRs about its centre"
            )
        device = Interferometer.table1(
            options["ports"], seed=options["seed"], fsr_hz=options["fsr"]
        )
        device, spectral_preset = _spectral(device, options)
        device = _thermal(_faulty(device, options), options)
        sweep_hz = device.sweep_hz(options["samples"], options["span_fsr"])
    options["noise_w"] = _noise_w(options, device.ports)
    varies = options["power_fluctuation"] > 0 or options["power_drift"] > 0
    options["monitor"] = varies and not options["no_monitor"]
    rng = _noise_rng(options)
    sweep_hz = np.tile(sweep_hz, options["repeat"])
    frequencies = [(_axis_column(x_unit), sweep_hz)]
    if test_samples:
        low, high = sweep_hz.min(), sweep_hz.max()
        frequencies.append((_axis_column(x_unit, "true_"), rng.uniform(low, high, test_samples)))
    temperatures = _temperatures_k(device, options, sweep_hz.size, test_samples, rng)
    drifts = [_sweep_drift(device, sweep_hz.size, options)] + [(None, None)] * bool(test_samples)
    tables = [  # everything is simulated before anything is written
        {
            axis: hz_to_axis(frequency, x_unit),
            **_readings(
                device,
                frequency,
                options,
                rng,
                printable(f"simulating {path}"),
                *drift,
                temperature_k=temperature,
            ),
        }
        for path, (axis, frequency), drift, temperature in zip(
            targets, frequencies, drifts, temperatures, strict=False
        )
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
    if cascade:
        for line in _cascade_text(device, band, options["seed"], options["spectral"]):
            say(quiet, line, err=messages_to_stderr)
        return
    say(
        quiet,
        f"device: Table 1, {device.ports} ports, seed {options['seed']}, true FSR "
        f"{fsr_text(device.true_fsr_hz)}, centre {optical_text(device.center_hz)}",
        err=messages_to_stderr,
    )
    if spectral_preset is not None or device.dispersion_s2 != 0:
        say(
            quiet,
            _spectral_text(device, spectral_preset, sweep_hz, options["spectral"]),
            err=messages_to_stderr,
        )
    if options["platform"] is not None:
        shift_hz = device.thermal_phase_rad_per_k * device.true_fsr_hz / (2 * np.pi)
        say(
            quiet,
            f"thermal: {options['platform']}, fringes move {shift_hz / 1e9:.4g} GHz/K, delay "
            f"{device.thermal_delay_per_k:.4g} /K about {device.reference_temperature_k:g} K; "
            f"sweep at {_temperature_text(tables[0]['temperature_k'])}",
            err=messages_to_stderr,
        )


command = simulate
