"""Mislabelled power units (issue 29, item 6): caught as the frequency axis's are.

Watt values under dBm headers, and dBm values under W/mW/uW/nW headers, are refused with
an error naming the column, the values, the unit they look like and the parameter that
says it; a unit the caller gives is taken as said. The edges of both rules are tested on
either side, and real dBm data (-90 to +20 dBm), dark readings in W (small offsets of
either sign) and voltages stay readable.
"""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.exceptions import InputError
from wavemeter.io import ColumnRequest, iter_readings, read_table, write_table
from wavemeter.io.checks import DBM_LIKE_BELOW, WATT_LIKE_MAX_DBM
from wavemeter.units import power_to_w

from .helpers import one_error
from .helpers import run_cli as run

ROWS = 400


@pytest.fixture(scope="module")
def sweep():
    """Frequencies (Hz) and port powers (W) of a Table 1 device over one FSR at 1 mW, with
    its detector noise (some readings near a fringe minimum are slightly negative)."""
    device = wm.Interferometer.table1(3, seed=6)
    frequency = device.sweep_hz(ROWS)
    powers = device.powers(frequency, 1e-3, 5e-7, rng=6)
    assert (powers < 0).any() and powers.max() < 1e-3
    return frequency, powers


def write(path, frequency, powers, unit: str):
    columns = {"frequency_hz": frequency}
    columns |= {f"p{k + 1}_{unit}": powers[:, k] for k in range(powers.shape[1])}
    write_table(path, columns)
    return path


def refused(path, request=None, **options) -> InputError:
    with pytest.raises(InputError) as error:
        read_table(path, request, **options)
    assert error.value.parameter == "power_unit"
    return error.value


def column_range(values: np.ndarray) -> str:
    return f"values {values.min():.4g} to {values.max():.4g}"


# ---------------------------------------------------------------------------- W as dBm
def test_watt_values_under_dbm_headers_are_refused_naming_the_unit(sweep, tmp_path):
    frequency, powers = sweep
    path = write(tmp_path / "s.csv", frequency, powers, "dBm")
    error = refused(path)
    assert str(error) == (
        f"{path}: column 'p1_dBm': {column_range(powers[:, 0])} labelled dBm look like W: none "
        "is above 0.1 and the negative ones are small beside the positive ones (a detector's "
        "noise or offset), while as dBm every reading would lie within 2.3 % of 1 mW; give "
        "the power unit W"
    )
    # said so, they are read as the W file is
    table = read_table(path, ColumnRequest(power_unit="W"))
    expected = read_table(write(tmp_path / "w.csv", frequency, powers, "w"))
    np.testing.assert_array_equal(table.powers_w, expected.powers_w)
    # a unit given is taken as said, also dBm
    assert read_table(path, ColumnRequest(power_unit="dBm")).n_rows == ROWS


def test_a_chunked_read_refuses_them_too(sweep, tmp_path):
    frequency, powers = sweep
    path = write(tmp_path / "s.csv", frequency, powers, "dBm")
    stream = iter_readings(path, chunk_rows=64)
    with pytest.raises(InputError, match=r"column 'p1_dBm': values .* labelled dBm look like W"):
        list(stream)


@pytest.mark.parametrize(
    ("values", "is_refused"),
    [
        ([WATT_LIKE_MAX_DBM, 0.02, -WATT_LIKE_MAX_DBM / 2], True),  # both edges, inside
        ([np.nextafter(WATT_LIKE_MAX_DBM, 1), 0.02, 0.01], False),  # above 0.1 dBm
        ([0.1, 0.02, np.nextafter(-0.05, -1)], False),  # a negative reading too large
        ([1e-6, 2e-6, 3e-6], True),
        ([0.0, -1e-9, -2e-9], False),  # nothing positive: no light in W, and dBm allows it
        ([-90.0, -30.0, 20.0], False),  # the range of real dBm readings
        ([0.5, 3.0, 20.0], False),  # positive dBm, above 1 mW everywhere
        ([-0.04, 0.0, 0.05], False),  # a steady 1 mW: readings either side of 0 dBm
    ],
)
def test_the_watt_like_rule_at_its_edges(tmp_path, values, is_refused):
    path = tmp_path / "s.csv"
    good = np.array([-20.0, -10.0, -5.0])
    write_table(path, {"p1_dBm": good, "p2_dBm": np.array(values), "p3_dBm": good})
    if is_refused:
        assert "column 'p2_dBm'" in str(refused(path, need_x=False))
    else:
        table = read_table(path, need_x=False)
        np.testing.assert_array_equal(table.powers_w[:, 1], power_to_w(values, "dBm"))


# ---------------------------------------------------------------------------- dBm as W
def test_dbm_values_under_milliwatt_headers_are_refused_naming_the_unit(sweep, tmp_path):
    """A 1.6 mW source: a port reads above 0 dBm near its fringe's top, so not every
    value is negative, yet most are far below any offset a detector has."""
    frequency, powers = sweep
    dbm = 10 * np.log10(np.clip(powers, 1e-9, None) * 1.6 / 1e-3)
    assert (dbm[:, 0] > 0).any() and (dbm[:, 0] <= -1).mean() > 0.5
    path = write(tmp_path / "s.csv", frequency, dbm, "mW")
    error = refused(path)
    column = dbm[:, 0]
    below = int(np.count_nonzero(column <= -1))
    assert str(error) == (
        f"{path}: column 'p1_mW': {column_range(column)} labelled mW look like dBm: {below} of "
        f"{ROWS} readings are -1 mW or less, and light is no negative power beyond a small "
        "detector offset; give the power unit dBm"
    )
    table = read_table(path, ColumnRequest(power_unit="dBm"))
    np.testing.assert_array_equal(table.powers_w, power_to_w(dbm, "dBm"))


@pytest.mark.parametrize("unit", ["W", "mW", "uW", "nW"])
@pytest.mark.parametrize(
    ("below", "is_refused"),
    [(2, False), (3, True)],  # of 5 readings: at half, past half
)
def test_the_dbm_like_rule_at_its_edges(tmp_path, unit, below, is_refused):
    column = np.array(
        [DBM_LIKE_BELOW] * below + [np.nextafter(DBM_LIKE_BELOW, 0)] + [5.0] * (4 - below)
    )
    good = np.full(5, 5.0)
    path = tmp_path / "s.csv"
    write_table(path, {f"p1_{unit}": good, f"p2_{unit}": column, f"p3_{unit}": good})
    if is_refused:
        message = str(refused(path, need_x=False))
        assert (
            f"column 'p2_{unit}': values -1 to 5 labelled {unit} look like dBm: 3 of 5" in message
        )
    else:
        table = read_table(path, need_x=False, allow_invalid=True)
        np.testing.assert_array_equal(table.powers_w[:, 1], power_to_w(column, unit))


def test_dark_readings_and_voltages_are_no_dbm(tmp_path):
    rng = np.random.default_rng(61)
    offsets = np.array([2e-6, -1e-6, 5e-7]) + 1e-6 * rng.standard_normal((200, 3))
    path = tmp_path / "dark.csv"
    write_table(path, {f"p{k + 1}_w": offsets[:, k] for k in range(3)})
    table = read_table(path, need_x=False, allow_invalid=True)
    np.testing.assert_array_equal(table.powers_w, offsets)
    volts = tmp_path / "v.csv"
    values = np.array([-3.0, -2.0, -1.5, 0.5])
    write_table(volts, {"DC CH1": values, "DC CH2": values, "DC CH3": values})
    assert read_table(volts, need_x=False, allow_invalid=True).n_rows == 4


# ---------------------------------------------------------------------------- command line
def test_calibrate_refuses_watt_values_under_dbm_headers_with_the_option(sweep, tmp_path, capsys):
    frequency, powers = sweep
    path = write(tmp_path / "s.csv", frequency, powers, "dBm")
    out = tmp_path / "c.wmcal.json"
    err = one_error(*run(capsys, f"calibrate {path} -o {out} --fsr 50GHz")[::2])
    assert err.startswith(f"error: {path}: column 'p1_dBm': {column_range(powers[:, 0])} ")
    assert err.endswith("give the power unit W (use --power-unit)\n")
    assert not out.exists()
    code, _, err = run(capsys, f"calibrate {path} -o {out} --fsr 50GHz --power-unit W --quiet")
    assert code == 0, err
