"""Units: names, exact conversions to SI, plausibility of frequency axes, round trips."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wavemeter.exceptions import InputError
from wavemeter.units import (
    FREQUENCY_UNITS,
    POWER_UNITS,
    SPEED_OF_LIGHT_M_S,
    WAVELENGTH_UNITS,
    axis_to_hz,
    canonical_unit,
    hz_to_axis,
    parse_frequency_hz,
    parse_optical_frequency_hz,
    parse_power_w,
    parse_quantity,
    power_to_w,
    temperature_to_k,
    w_to_power,
)


def test_speed_of_light_is_the_exact_si_value():
    assert SPEED_OF_LIGHT_M_S == 299_792_458.0


@pytest.mark.parametrize(
    ("written", "kind", "canonical"),
    [
        ("thz", "axis", "THz"),
        ("GHZ", "frequency", "GHz"),
        ("Hz", "axis", "Hz"),
        ("µm", "axis", "um"),
        ("μm", "wavelength", "um"),
        ("NM", "axis", "nm"),
        ("mw", "power", "mW"),
        ("µW", "power", "uW"),
        ("DBM", "power", "dBm"),
        ("v", "power", "V"),
        ("°C", "temperature", "C"),
        ("degC", "temperature", "C"),
        ("k", "temperature", "K"),
    ],
)
def test_unit_names_are_matched_without_case_and_with_micro_signs(written, kind, canonical):
    assert canonical_unit(written, kind) == canonical


@pytest.mark.parametrize(("unit", "kind"), [("mA", "power"), ("nm", "power"), ("dB", "axis")])
def test_unknown_unit_names_the_column_the_unit_and_the_allowed_ones(unit, kind):
    with pytest.raises(ValueError, match=rf"column 'P1_x': unknown {kind} unit '{unit}'") as err:
        canonical_unit(unit, kind, "column 'P1_x'")
    allowed = {"power": POWER_UNITS, "axis": {**FREQUENCY_UNITS, **WAVELENGTH_UNITS}}[kind]
    assert all(name in str(err.value) for name in allowed)


def test_wavelength_to_vacuum_frequency_reference_values():
    # c / 1550 nm = 193 414 489 032 258.06... Hz; c / 1.5 um = 199.861638666... THz
    assert axis_to_hz([1550.0], "nm")[0] == pytest.approx(193414489032258.0645, rel=1e-15)
    assert axis_to_hz([1.5], "um")[0] == pytest.approx(199861638666666.6667, rel=1e-15)
    assert axis_to_hz([1.55e-6], "m")[0] == pytest.approx(193414489032258.0645, rel=1e-15)
    assert hz_to_axis([193.4e12], "nm")[0] == pytest.approx(1550.1161220268873, rel=1e-15)


def test_frequency_units_scale_exactly():
    assert axis_to_hz([193.4], "THz")[0] == 193.4e12
    assert axis_to_hz([193400.0], "GHz")[0] == 193.4e12
    assert axis_to_hz([193.4e12], "Hz")[0] == 193.4e12
    assert hz_to_axis([193.4e12], "THz")[0] == 193.4


def test_power_units_reference_values():
    assert power_to_w([0.0, 10.0, -30.0], "dBm") == pytest.approx([1e-3, 1e-2, 1e-6], rel=1e-15)
    assert power_to_w([1.0], "mW")[0] == 1e-3
    assert power_to_w([2.5], "uW")[0] == 2.5e-6
    assert power_to_w([7.0], "nW")[0] == 7e-9
    assert power_to_w([0.4], "V")[0] == 0.4  # relative, linear: kept as written
    assert w_to_power([1e-3, 0.0, -1e-9], "dBm").tolist() == [0.0, -np.inf, -np.inf]


def test_temperature_to_kelvin():
    assert temperature_to_k([25.0, -273.15], "C").tolist() == [298.15, 0.0]
    assert temperature_to_k([300.0], "K")[0] == 300.0


@pytest.mark.parametrize(
    ("values", "unit", "expected"),
    [
        (
            [1530.0, 1560.0],
            "THz",
            "values 1530-1560 labelled THz look like nm; give the axis unit nm",
        ),
        ([193.4e12, 193.5e12], "THz", "look like Hz; give the axis unit Hz"),
        ([192.0, 196.0], "nm", "look like THz; give the axis unit THz"),
        ([1.53, 1.56], "nm", "look like um; give the axis unit um"),
        ([1.0, 5.0], "Hz", "are not optical"),
    ],
)
def test_implausible_axis_suggests_the_unit_it_looks_like(values, unit, expected):
    with pytest.raises(InputError, match="column 'freq'") as err:
        axis_to_hz(values, unit, "freq")
    assert expected in str(err.value) and err.value.parameter == "x_unit"


@pytest.mark.parametrize(
    ("text", "hz"),
    [
        ("50GHz", 50e9),
        ("49.69 GHz", 49.69e9),
        ("5e10", 5e10),
        ("0.05 thz", 0.05e12),
        (".5THz", 0.5e12),
        ("50000 MHz", 50e9),
    ],
)
def test_parse_frequency_with_unit(text, hz):
    assert parse_frequency_hz(text) == pytest.approx(hz, rel=1e-15)


@pytest.mark.parametrize("text", ["fast", "50 parsecs", "GHz", "50 nm", ""])
def test_parse_frequency_rejects_other_text(text):
    with pytest.raises(ValueError, match="--fsr"):
        parse_frequency_hz(text, "--fsr")


@pytest.mark.parametrize(
    ("text", "watts"),
    [
        ("1mW", 1e-3),
        ("5e-7 W", 5e-7),
        ("0.5 uW", 5e-7),
        ("500nW", 5e-7),
        ("0dBm", 1e-3),
        ("-30 dBm", 1e-6),
        ("1e-3", 1e-3),  # bare: W
        ("2 µW", 2e-6),
    ],
)
def test_parse_power_with_unit(text, watts):
    assert parse_power_w(text, "--power") == pytest.approx(watts, rel=1e-15)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("1V", "--power '1V': V is a relative detector scale, not a power"),
        ("1 mA", "--power: unknown power unit 'mA'"),
        ("loud", "--power 'loud' is not a number with an optional unit (e.g. 1mW"),
        ("1e999 W", "--power '1e999 W' is not a finite number"),
    ],
)
def test_parse_power_rejects_other_text(text, expected):
    with pytest.raises(ValueError) as err:
        parse_power_w(text, "--power")
    assert expected in str(err.value)


@pytest.mark.parametrize(
    ("text", "hz"),
    [
        ("193.4THz", 193.4e12),
        ("1550nm", 299792458 / 1550e-9),
        ("1.55 um", 299792458 / 1.55e-6),
        ("1.934e14", 1.934e14),
    ],
)
def test_parse_optical_frequency_takes_a_vacuum_wavelength(text, hz):
    assert parse_optical_frequency_hz(text) == pytest.approx(hz, rel=1e-15)


def test_parse_quantity_keeps_the_number_and_says_whether_a_unit_was_given():
    assert parse_quantity("50", "frequency") == (50.0, None)
    assert parse_quantity(" 50 ghz ", "frequency") == (50.0, "GHz")
    assert parse_quantity("-3dbm", "power") == (-3.0, "dBm")
    with pytest.raises(ValueError, match="wavelength must be > 0"):
        parse_optical_frequency_hz("0nm")


@given(
    frequency_hz=st.floats(min_value=100e12, max_value=1000e12),
    unit=st.sampled_from(sorted({**FREQUENCY_UNITS, **WAVELENGTH_UNITS})),
)
def test_axis_round_trip(frequency_hz, unit):
    back = axis_to_hz(hz_to_axis([frequency_hz], unit), unit)[0]
    assert back == pytest.approx(frequency_hz, rel=4e-16)


@given(
    power_w=st.floats(min_value=1e-12, max_value=10.0),
    unit=st.sampled_from(sorted(set(POWER_UNITS) - {"V"})),
)
def test_power_round_trip(power_w, unit):
    back = power_to_w(w_to_power([power_w], unit), unit)[0]
    assert back == pytest.approx(power_w, rel=1e-14)
