"""The wide-band coverage study (benchmarks/_wideband_coverage.py, ``wideband.py --coverage``).

Its truth is the one the tests use (``tests/_fringe.py``, the same definition written
twice: the benchmarks do not import the tests); its targets fail on standard errors that
are too small or too large and pass on Gaussian z-scores; one small seed runs end to end.
The coverage numbers themselves come from the benchmark run (docs/results.rst).
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from wavemeter.simulation import Scenario

from ._fringe import true_fringe_coefficients_s
from .helpers import BENCHMARKS


@pytest.fixture(scope="module")
def coverage():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("_wideband_coverage")


def test_the_benchmark_truth_is_the_tests_truth(coverage):
    device = Scenario(seed=3, spectral="sin", dispersion_s2=1e-26, span_fsr=24.0).device
    center_hz, half_hz = 193.2e12, 12 * 50e9
    benchmark = coverage.true_fringe_coefficients_s(device, center_hz, half_hz, 3)
    np.testing.assert_allclose(
        benchmark, true_fringe_coefficients_s(device, center_hz, half_hz, 3), rtol=1e-12
    )


def _outcomes(z_fringe: np.ndarray, z_readings: np.ndarray) -> list[dict]:
    """Outcomes of the shape ``run_seed`` gives: one calibration of orders (1, 0) per seed,
    and its readings."""
    stages = [
        {
            "label": "case",
            "orders": (1, 0),
            "z": np.array([z]),
            "std": np.array([1e-18]),
            "model_z": np.array([z]),
            "model_std": np.array([1e-18]),
        }
        for z in z_fringe
    ]
    readings = [{"label": "case", "reading_z": z, "flagged": 0} for z in z_readings]
    return stages + readings


def _status(table: str) -> str:
    row = table.splitlines()[2]
    return "PASS" if "PASS" in row else "FAIL" if "FAIL" in row else "-"


@pytest.mark.parametrize(("scale", "expected"), [(1.0, "PASS"), (2.0, "FAIL"), (0.4, "FAIL")])
def test_targets_pass_gaussian_z_and_fail_wrong_standard_errors(coverage, scale, expected):
    """30 seeds and 8 x 2000 readings of z = scale x N(0, 1): a stated std half the true
    one (scale 2) or 2.5 times it (0.4) fails both targets."""
    rng = np.random.default_rng(11)
    seeds = scale * rng.standard_normal(30)
    readings = scale * rng.standard_normal((8, 2000))
    outcomes = _outcomes(seeds, list(readings))
    assert _status(coverage.coverage_table(outcomes)) == expected
    assert _status(coverage.reading_table(outcomes)) == expected


def test_target_bands_follow_the_count(coverage):
    """The band of a standard deviation of S values is 3 of its standard errors
    1 / sqrt(2 (S - 1)); the share within 1.96 may fall 3 binomial deviations below 95 %."""
    assert coverage.std_band(51) == pytest.approx(3.0 / 10.0)
    assert coverage.coverage_floor(19) == pytest.approx(0.95 - 3.0 * 0.05)


def test_one_small_seed_end_to_end(coverage, monkeypatch):
    """A 12-FSR sweep of the user guide's device: every outcome finite, the readings read
    inside the band."""
    monkeypatch.setattr(coverage, "TEST_READINGS", 400)
    fields = {"spectral": "sin", "dispersion_s2": 1e-26, "span_fsr": 12.0, "samples": 3600}
    outcomes = coverage.run_seed(coverage.CoverageCase("small", "12 FSRs", fields), seed=4)
    stage, reading = outcomes
    assert stage["label"] == "small" and len(stage["z"]) == stage["orders"][0]
    assert np.all(np.isfinite(stage["z"])) and np.all(stage["std"] > 0)
    assert reading["reading_z"].shape == (400,) and reading["flagged"] == 0
    assert np.all(np.isfinite(reading["reading_z"]))
    # 400 Gaussian z: std within 4 of its standard errors 1 / sqrt(2 x 399) of 1
    assert abs(np.std(reading["reading_z"], ddof=1) - 1.0) < 4.0 / np.sqrt(2 * 399)


def test_a_coefficient_of_few_seeds_is_shown_not_judged(coverage):
    """Under ``MIN_JUDGED_SEEDS`` seeds the z std is printed without a verdict."""
    z = 3.0 * np.random.default_rng(5).standard_normal(coverage.MIN_JUDGED_SEEDS - 1)
    row = coverage.coverage_table(_outcomes(z, [])).splitlines()[2]
    assert "not judged" in row and "PASS" not in row and "FAIL" not in row
