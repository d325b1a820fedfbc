"""Smoke test of the thermal benchmark (benchmarks/thermal.py) on one 3-port device."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from PIL import Image

import wavemeter as wm
from wavemeter.simulation import THERMAL_PRESETS

from .helpers import BENCHMARKS, table_rows

pytestmark = pytest.mark.slow

TEST_SAMPLES = 300
GRID_SAMPLES = 60
#: the RMS of M test errors has a relative standard error of about 1 / sqrt(2 M) (4 % at
#: 300): the 1.2 target plus five of them
NEAR_BOUND = 1.2 + 5.0 / np.sqrt(2 * TEST_SAMPLES)


@pytest.fixture(scope="module")
def thermal():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("thermal")


@pytest.fixture(scope="module")
def result(thermal):
    return thermal.evaluate_device(
        3, 0, seed=1, test_samples=TEST_SAMPLES, grid_samples=GRID_SAMPLES
    )


def test_tables_have_their_headers_and_a_row_per_port_count(thermal, result):
    for scenario in thermal.SCENARIOS:
        rows = table_rows(thermal.scenario_table(scenario, [result]))
        assert rows[0][: len(thermal.SCENARIO_HEADERS)] == list(thermal.SCENARIO_HEADERS)
        assert all(len(row) == len(rows[0]) for row in rows)
        assert [row[0] for row in rows[2:]] == ["3"]
    summary = table_rows(thermal.summary_table([result]))
    assert summary[0][1:] == [scenario.title for scenario in thermal.SCENARIOS]
    assert all(len(row) == len(summary[0]) for row in summary)
    assert summary[-1][1:] == [
        "PASS" if result.outcomes[s.key].over_bound() <= thermal.TARGET_OVER_BOUND else "FAIL"
        for s in thermal.SCENARIOS
    ]
    grid = table_rows(thermal.grid_table([result]))
    assert grid[0] == list(thermal.GRID_HEADERS)
    assert [float(row[0]) for row in grid[2:]] == list(thermal.GRID_TEMPERATURES_K)
    anchored = table_rows(thermal.reanchor_table([result]))
    assert [row[0] for row in anchored[2:]] == [label for label, _, _ in thermal.REANCHOR_BINS]
    verdict = thermal.verdict([result])
    assert len(verdict) == len(thermal.SCENARIOS) + 2
    assert all(line.startswith(("PASS ", "FAIL ")) for line in verdict)


def test_the_bound_adds_the_sensor_noise_times_the_true_fringe_shift(thermal, result):
    """SiN moves the fringes 2.6 GHz/K at the centre (the preset): with 1 mK the bound is
    the CRLB and 2.6 MHz in quadrature, to the delay's share of the rate (< 1e-3)."""
    sin = result.outcomes["sin"]
    excess = np.sqrt(sin.bound_hz**2 - sin.crlb_hz**2)
    assert excess == pytest.approx(2.6e9 * 1e-3, rel=1e-3)


def test_thermal_is_near_the_bound_where_plain_is_off_by_gigahertz(thermal, result):
    """Plain at 293 K reads a chip at T off by the fringe shift 2.6 GHz/K (T - 293 K) modulo
    the FSR; the ThermalCalibrator stays near its bound of about 10 MHz."""
    sin = result.outcomes["sin"]
    shift_hz = THERMAL_PRESETS["sin"].fringe_shift_hz_per_k * (
        sin.temperature_k - thermal.PLAIN_TEMPERATURE_K
    )
    expected_plain_hz = thermal.rms(wm.frequency_error_hz(shift_hz, 0.0, sin.device.true_fsr_hz))
    plain_hz = thermal.rms(sin.plain_error_hz[thermal.PLAIN_293])
    # besides the shift: detector noise (~10 MHz) and the delay's change (< 4 MHz)
    assert plain_hz == pytest.approx(expected_plain_hz, rel=0.01)
    assert plain_hz > 1e9
    assert sin.over_bound() < NEAR_BOUND
    assert plain_hz / thermal.rms(sin.thermal_error_hz) > 100


def test_reanchoring_brings_the_plain_calibration_back_to_the_crlb(thermal, result):
    """Near 293 K one line of 50 readings re-measures the bias: its share of the variance
    is 1/50, the map's error of a 2000-sample sweep a few per cent."""
    ratio = thermal.reanchor_ratio(result, 0.0, thermal.REANCHOR_WINDOW_K)
    readings = GRID_SAMPLES * sum(
        abs(t - thermal.PLAIN_TEMPERATURE_K) <= thermal.REANCHOR_WINDOW_K
        for t in thermal.GRID_TEMPERATURES_K
    )
    assert ratio < 1.2 + 5.0 / np.sqrt(2 * readings)


def test_the_figure_is_a_palette_png(thermal, result, tmp_path):
    path = tmp_path / "thermal.png"
    thermal.write_figure([result], path)
    with Image.open(path) as image:
        assert image.format == "PNG" and image.mode == "P"
    assert [p.name for p in tmp_path.iterdir()] == ["thermal.png"]


@pytest.mark.parametrize(
    ("argv", "named"),
    [(["--devices", "0"], "--devices"), (["--figure", "figure.svg"], "--figure")],
)
def test_bad_arguments_are_one_error_line_and_exit_code_2(thermal, capsys, argv, named):
    with pytest.raises(SystemExit) as stop:
        thermal.main(argv)
    assert stop.value.code == 2
    printed = capsys.readouterr()
    assert printed.out == ""
    lines = printed.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and named in lines[0]
