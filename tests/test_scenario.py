"""``wavemeter.simulation.Scenario``: what ``wavemeter simulate`` writes, from Python.

The command's files, read back as text, hold exactly the values of ``Scenario(...).tables()``
and ``laser_table()`` for the same options (each written float parsed with ``float()`` and
compared with ``==``); the scenario refuses what the command refuses, naming the field,
and the command prints the same refusal under its option's name.
"""

from __future__ import annotations

import dataclasses
import doctest

import numpy as np
import pytest

import wavemeter.simulation.scenario as scenario_module
from wavemeter.exceptions import InputError
from wavemeter.io import SENTINEL_DBM
from wavemeter.simulation import Scenario

from .helpers import assert_file_holds, one_error, run_cli

#: option sets of ``wavemeter simulate`` and the same scenario in library names and SI units
CASES = {
    "plain": ("--test 300", {"test": 300}),
    "defaults": ("", {}),
    "units and no-reading codes": (
        "--write-axis-unit nm --write-power-unit dBm --noise 5e-5W --samples 500 --test 50 "
        "--seed 3",
        {
            "x_unit": "nm",
            "power_unit": "dBm",
            "noise_w": 5e-5,
            "samples": 500,
            "test": 50,
            "seed": 3,
        },
    ),
    "thermal ramp": (
        "--platform soi --ramp-k 290:300 --repeat 3 --samples 200 --test 100 --seed 4",
        {
            "platform": "soi",
            "ramp_k": (290.0, 300.0),
            "repeat": 3,
            "samples": 200,
            "test": 100,
            "seed": 4,
        },
    ),
    "thermal at a temperature": (
        "--platform sin --temperature-k 20C --samples 300 --test 30",
        {"platform": "sin", "temperature_k": 293.15, "samples": 300, "test": 30},
    ),
    "wide band": (
        "--spectral sin --dispersion 1e-26 --span-fsr 24 --samples 4800 --test 500 --seed 2",
        {
            "spectral": "sin",
            "dispersion_s2": 1e-26,
            "span_fsr": 24.0,
            "samples": 4800,
            "test": 500,
            "seed": 2,
        },
    ),
    "slopes alone": (
        "--coupler-slope 0.02 --responsivity-slope 0.004 --span-fsr 10 --samples 500 --fsr 40GHz",
        {
            "coupler_slope_sigma_per_thz": 0.02,
            "responsivity_slope_sigma_per_thz": 0.004,
            "span_fsr": 10.0,
            "samples": 500,
            "fsr_hz": 40e9,
        },
    ),
    "cascade": (
        "--cascade 5THz,500GHz,50GHz --spectral sin --samples 3000 --test 400 --power 2mW",
        {
            "cascade_fsrs_hz": (5e12, 500e9, 50e9),
            "spectral": "sin",
            "samples": 3000,
            "test": 400,
            "power_w": 2e-3,
        },
    ),
    "cascade of 10-port stages over a band": (
        "--cascade 1.5THz,150GHz --band 192.9THz:193.9THz --ports 10 --samples 200 --test 20",
        {
            "cascade_fsrs_hz": (1.5e12, 150e9),
            "band_hz": (192.9e12, 193.9e12),
            "ports": 10,
            "samples": 200,
            "test": 20,
        },
    ),
    "faults": (
        "--dark-offset 2uW,0,-1uW --port-noise 5e-7,2e-6,5e-7 --power-drift 0.05 "
        "--thermal-drift 0.5 --power-fluctuation 0.01 --samples 400 --test 200 --seed 5",
        {
            "dark_offset_w": (2e-6, 0.0, -1e-6),
            "port_noise_w": (5e-7, 2e-6, 5e-7),
            "power_drift": 0.05,
            "thermal_drift_k": 0.5,
            "power_fluctuation": 0.01,
            "samples": 400,
            "test": 200,
            "seed": 5,
        },
    ),
    "drift without a monitor": (
        "--power-drift 0.05 --no-monitor --samples 100 --test 10",
        {"power_drift": 0.05, "monitor": False, "samples": 100, "test": 10},
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_command_writes_the_scenarios_tables_bit_for_bit(tmp_path, capsys, case):
    options, fields = CASES[case]
    sweep_path = tmp_path / "s.csv"
    code, _, err = run_cli(capsys, f"simulate -o {sweep_path} {options} --quiet")
    assert code == 0, err
    sweep, test = Scenario(**fields).tables()
    assert_file_holds(sweep_path, sweep)
    if test is None:
        assert not (tmp_path / "s-test.csv").exists()
    else:
        assert_file_holds(tmp_path / "s-test.csv", test)


def test_the_laser_file_is_the_scenarios_laser_table(tmp_path, capsys):
    options = (
        "--laser 3000 --laser-rate 1MHz --white-fm 1e9 --flicker-fm 1e12 "
        "--random-walk-fm 1e15 --laser-drift -2e9 --laser-frequency 1550nm --platform sin "
        "--samples 50 --test 5"
    )
    laser_path = tmp_path / "laser.csv"
    code, printed, err = run_cli(
        capsys, f"simulate -o {tmp_path / 's.csv'} --laser-out {laser_path} {options}"
    )
    assert code == 0, err
    scenario = Scenario(
        laser=3000,
        laser_rate_hz=1e6,
        white_fm_hz2_per_hz=1e9,
        flicker_fm_hz2=1e12,
        random_walk_fm_hz2_per_s=1e15,
        laser_drift_hz_per_s=-2e9,
        laser_center_hz=299792458 / 1550e-9,
        platform="sin",
        samples=50,
        test=5,
    )
    laser = scenario.laser_table()
    assert_file_holds(laser_path, laser)
    assert list(laser)[:2] == ["time_s", "true_frequency_hz"] and "temperature_k" in laser
    assert laser["time_s"][1] == 1e-6
    assert f"wrote {laser_path} (3000 rows: time_s, true_frequency_hz, p1_w" in printed
    assert "laser: 3000 readings at 1 MHz" in printed and "white FM 1e+09 Hz^2/Hz" in printed
    # the laser has a stream of its own: the sweep and test files are those without it
    sweep, test = Scenario(platform="sin", samples=50, test=5).tables()
    assert_file_holds(tmp_path / "s.csv", sweep)
    assert_file_holds(tmp_path / "s-test.csv", test)


def test_dbm_readings_at_a_null_are_the_readers_no_reading_code():
    sweep, _ = Scenario(**CASES["units and no-reading codes"][1]).tables()
    ports = np.column_stack([values for name, values in sweep.items() if name.endswith("_dBm")])
    assert np.count_nonzero(ports == SENTINEL_DBM) > 0  # noise 5e-5 W at 1 mW reaches 0 W
    assert np.all((ports == SENTINEL_DBM) | (ports > -60))


def test_a_scenario_is_reproducible_and_checked_again_when_replaced():
    scenario = Scenario(samples=20, test=5, power_fluctuation=0.02)
    first, again = scenario.tables(), Scenario(samples=20, test=5, power_fluctuation=0.02).tables()
    for one, other in zip(first, again, strict=True):
        assert one.keys() == other.keys()
        assert all(np.array_equal(one[name], other[name]) for name in one)
    assert scenario == Scenario(samples=20, test=5, power_fluctuation=0.02)
    assert hash(scenario) == hash(Scenario(samples=20, test=5, power_fluctuation=0.02))
    with pytest.raises(dataclasses.FrozenInstanceError):
        scenario.samples = 30
    with pytest.raises(InputError) as error:
        dataclasses.replace(scenario, samples=2)
    assert error.value.parameter == "samples"


def test_values_are_kept_in_one_spelling():
    scenario = Scenario(
        ports=np.int64(4),
        dark_offset_w=1e-6,
        ramp_k=[290, 300],
        platform="sin",
        x_unit="thz",
        power_unit="mw",
    )
    assert type(scenario.ports) is int and scenario.dark_offset_w == (1e-6,)
    assert scenario.ramp_k == (290.0, 300.0) and (scenario.x_unit, scenario.power_unit) == (
        "THz",
        "mW",
    )
    np.testing.assert_array_equal(scenario.device.dark_offset_w, np.full(4, 1e-6))
    assert list(scenario.tables()[0])[:2] == ["frequency_THz", "p1_mW"]


def test_progress_is_advanced_over_every_row_of_every_table():
    advanced: dict[str, list[int]] = {}

    class Bar:
        def __init__(self, table, total):
            self.table, self.total = table, total

        def __enter__(self):
            advanced[self.table] = [self.total]
            return advanced[self.table].append

        def __exit__(self, *exc):
            return False

    def progress(table, total, unit):
        assert unit == "rows"
        return Bar(table, total)

    scenario = Scenario(samples=100, repeat=2, test=30, laser=40)
    with_bar = scenario.tables(progress)
    assert {name: (steps[0], sum(steps[1:])) for name, steps in advanced.items()} == {
        "sweep": (200, 200),
        "test": (30, 30),
    }
    assert scenario.laser_table(progress)["time_s"].size == 40 and advanced["laser"] == [40, 40]
    without = scenario.tables()
    assert all(np.array_equal(with_bar[0][k], without[0][k]) for k in without[0])


# ---------------------------------------------------------------------------- refusals
#: (scenario fields, the field named, part of the message) of values the scenario refuses
REFUSED = [
    ({"ports": 2}, "ports", "ports must be an integer from 3 to 64, got 2"),
    ({"ports": 65}, "ports", "from 3 to 64"),
    ({"ports": 3.0}, "ports", "must be an integer"),
    ({"seed": -1}, "seed", "seed must be an integer >= 0"),
    ({"samples": 3}, "samples", "samples must be an integer >= 4"),
    ({"span_fsr": 0.0}, "span_fsr", "span_fsr must be a finite number > 0"),
    ({"span_fsr": float("inf")}, "span_fsr", "got inf"),
    ({"span_fsr": float("nan")}, "span_fsr", "got nan"),
    ({"power_w": 0.0}, "power_w", "power_w must be a finite number > 0 (W)"),
    ({"noise_w": -1e-7}, "noise_w", ">= 0 (W)"),
    ({"fsr_hz": -5e10}, "fsr_hz", "> 0 (Hz)"),
    ({"test": -1}, "test", "test must be an integer >= 0"),
    ({"x_unit": "W"}, "x_unit", "x_unit: unknown axis unit 'W'"),
    ({"power_unit": "V"}, "power_unit", "power_unit V is not a simulated output"),
    ({"power_unit": "A"}, "power_unit", "unknown power unit 'A'"),
    ({"power_fluctuation": 0.5}, "power_fluctuation", "in [0, 0.3]"),
    ({"dark_offset_w": (1e-6, 2e-6)}, "dark_offset_w", "has 2 value(s) for 3 ports"),
    ({"dark_offset_w": (float("nan"),)}, "dark_offset_w", "finite"),
    ({"port_noise_w": (1e-7, -1e-7, 0.0)}, "port_noise_w", ">= 0 (W)"),
    ({"port_noise_w": (1e-7,)}, "port_noise_w", "give 3, one per port"),
    ({"port_noise_w": (1e-7,) * 3, "noise_w": 1e-7}, "port_noise_w", "not both"),
    ({"dispersion_s2": float("nan")}, "dispersion_s2", "finite"),
    ({"spectral": "soi"}, "spectral", "spectral must be one of 'sin'"),
    ({"coupler_slope_sigma_per_thz": -0.01}, "coupler_slope_sigma_per_thz", ">= 0"),
    ({"power_drift": 1.0}, "power_drift", "in [0, 1)"),
    ({"thermal_drift_k": float("inf")}, "thermal_drift_k", "finite"),
    ({"platform": "gaas"}, "platform", "one of 'sin', 'soi'"),
    ({"temperature_k": 290.0}, "platform", "temperature_k needs a thermal device"),
    ({"ramp_k": (290.0, 291.0)}, "platform", "ramp_k needs a thermal device"),
    (
        {"platform": "sin", "temperature_k": 290.0, "ramp_k": (290.0, 291.0)},
        "ramp_k",
        "give one of them",
    ),
    ({"platform": "sin", "ramp_k": (290.0,)}, "ramp_k", "2 numbers"),
    ({"platform": "sin", "temperature_k": 0.0}, "temperature_k", "> 0 (K)"),
    ({"repeat": 0}, "repeat", "repeat must be an integer >= 1"),
    ({"monitor": "no"}, "monitor", "True or False"),
    ({"band_hz": (191e12, 195e12)}, "band_hz", "band_hz is the band of a cascade"),
    (
        {"cascade_fsrs_hz": (5e12, 500e9, 50e9), "band_hz": (195e12, 191e12)},
        "band_hz",
        "low < high",
    ),
    ({"cascade_fsrs_hz": (5e12, 500e9, 50e9), "fsr_hz": 50e9}, "fsr_hz", "not simulated for a"),
    ({"cascade_fsrs_hz": (5e12, 500e9, 50e9), "span_fsr": 1.0}, "span_fsr", "covers band_hz"),
    ({"cascade_fsrs_hz": (5e12, 500e9, 50e9), "platform": "sin"}, "platform", "single devices"),
    ({"cascade_fsrs_hz": (5e12, 500e9, 50e9), "thermal_drift_k": 0.0}, "thermal_drift_k", "a"),
    ({"cascade_fsrs_hz": (50e9, 500e9, 5e12)}, "cascade_fsrs_hz", "of decreasing FSR"),
    ({"cascade_fsrs_hz": (5e12,)}, "cascade_fsrs_hz", "two or more stages"),
    ({"cascade_fsrs_hz": (1e12, 100e9, 10e9)}, "band_hz", "does not exceed the band"),
    (
        {"cascade_fsrs_hz": (5e12, 500e9, 50e9), "port_noise_w": (1e-7,) * 3},
        "port_noise_w",
        "3 value(s) for 9 ports",
    ),
    ({"laser": -1}, "laser", "laser must be an integer >= 0"),
    ({"laser": 10, "laser_rate_hz": 0.0}, "laser_rate_hz", "> 0 (Hz)"),
    ({"laser": 10, "laser_center_hz": 50e9}, "laser_center_hz", "in [1e+14, 1e+15]"),
    ({"laser": 10, "white_fm_hz2_per_hz": -1.0}, "white_fm_hz2_per_hz", ">= 0 (Hz^2/Hz)"),
    ({"laser": 10, "laser_drift_hz_per_s": float("nan")}, "laser_drift_hz_per_s", "finite"),
    ({"white_fm_hz2_per_hz": 1e8}, "laser", "none are asked for (laser is 0)"),
    ({"laser_rate_hz": 1e6}, "laser", "laser_rate_hz describes the laser"),
    (
        {"responsivity_slope_sigma_per_thz": 10.0, "span_fsr": 88.0},
        "responsivity_slope_per_thz",
        "makes the responsivity of port",
    ),
]


@pytest.mark.parametrize(("fields", "parameter", "message"), REFUSED)
def test_the_scenario_refuses_bad_values_naming_the_field(fields, parameter, message):
    with pytest.raises(InputError) as error:
        Scenario(**fields)
    assert error.value.parameter == parameter
    assert message in str(error.value)
    assert "--" not in str(error.value)  # library words, no command-line flags


#: (simulate options, the option the refusal names, part of the line) for refusals that
#: the scenario makes and the command prints in its own words
REFUSED_BY_THE_COMMAND = [
    ("--dark-offset 1uW,2uW", "--dark-offset has 2 value(s) for 3 ports: give one for all"),
    ("--port-noise 1e-7,1e-7,1e-7 --noise 5e-7W", "give --noise (every port) or --port-noise"),
    ("--temperature-k 290", "--temperature-k needs a thermal device: choose a platform"),
    ("--temperature-k 290", "(use --platform)"),
    ("--cascade 5THz,500GHz,50GHz --fsr 50GHz", "--fsr is not simulated for a cascade (--cascade)"),
    ("--cascade 5THz,500GHz,50GHz --thermal-drift 0", "--thermal-drift is not simulated"),
    ("--band 191THz:195.4THz", "a single device's sweep is --span-fsr FSRs about its centre"),
    ("--cascade 1THz,100GHz,10GHz", "give a narrower --band or a coarser first stage"),
    ("--write-axis-unit W", "--write-axis-unit: unknown axis unit 'W'"),
    ("--write-power-unit V", "--write-power-unit V is not a simulated output"),
    ("--span-fsr inf", "--span-fsr must be a finite number > 0 (FSRs), got inf"),
    ("--white-fm 1e8", "--white-fm describes the laser of the laser readings"),
    ("--white-fm 1e8", "(use --laser)"),
    ("--laser-rate 1MHz", "--laser-rate describes the laser"),
    (
        "--responsivity-slope 10 --span-fsr 88",
        "(responsivity_slope_per_thz: --responsivity-slope)",
    ),
]


@pytest.mark.parametrize(("options", "expected"), REFUSED_BY_THE_COMMAND)
def test_the_command_prints_the_scenarios_refusal_in_its_options(
    tmp_path, capsys, options, expected
):
    out = tmp_path / "s.csv"
    line = one_error(*run_cli(capsys, f"simulate -o {out} --samples 20 {options}")[::2])
    assert expected in line, line
    assert not out.exists()


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--laser 10 -o -", "with -o - (stdout) and --laser, name the laser file with --laser-out"),
        ("--laser 10 --laser-out {out}", "--laser-out {out} is the sweep file too"),
        ("--laser 10 --test 10 --laser-out {test}", "--laser-out {test} is the test file too"),
    ],
)
def test_the_laser_file_is_a_file_of_its_own(tmp_path, capsys, options, expected):
    out, test = tmp_path / "s.csv", tmp_path / "s-test.csv"
    options = options.format(out=out, test=test)
    command = f"simulate --samples 20 {options}" + ("" if "-o -" in options else f" -o {out}")
    line = one_error(*run_cli(capsys, command)[::2])
    assert expected.format(out=out, test=test) in line
    assert not out.exists() and not test.exists()


def test_the_docstring_examples_run():
    result = doctest.testmod(scenario_module, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 10 and result.failed == 0
