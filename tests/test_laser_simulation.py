"""The simulated laser: power-law noise of the stated levels, drift, reproducibility, bad input.

Tolerances come from the estimators' own statistics (chi-square for the PSD, Greenhall's
degrees of freedom for the Allan deviation) at stated confidence levels, with fixed seeds.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import get_window, welch
from scipy.stats import chi2

from wavemeter.analysis.noise_spectrum import band_covariance
from wavemeter.analysis.power_law import (
    power_law_deviations,
    power_law_psd_hz2_per_hz,
    slope_variance,
    welch_expectation,
)
from wavemeter.exceptions import InputError
from wavemeter.simulation import laser_frequency_hz

RATE_HZ = 1e6
CENTER_HZ = 193.4e12
LEVELS = {
    "white": {"white_fm_hz2_per_hz": 1e4},
    "flicker": {"flicker_fm_hz2": 1e8},
    "random_walk": {"random_walk_fm_hz2_per_s": 1e11},
}
TERM = {"white": 0, "flicker": 1, "random_walk": 2}


def test_welch_expectation_is_the_power_law_between_leakage_and_the_sample_averaging():
    """At bins well above the window's leakage and well below the rate, the exact
    expectation of the Welch estimate is h0, h_-1 / f and h_-2 / f^2."""
    length = 4096
    expected = welch_expectation(get_window("hann", length), RATE_HZ)
    bins = np.arange(32, length // 40)
    freqs = bins * RATE_HZ / length
    for index, kwargs in enumerate(LEVELS.values()):
        level = next(iter(kwargs.values()))
        analytic = power_law_psd_hz2_per_hz(freqs, **kwargs) / level
        # leakage of 1/f^2 through the Hann window: ~1/k^2; sample averaging: (f/rate)^2
        np.testing.assert_allclose(expected[index, bins], analytic, rtol=2e-3)


@pytest.mark.slow
@pytest.mark.parametrize("noise", LEVELS)
def test_welch_psd_of_each_noise_matches_its_level_within_the_chi_square_interval(noise):
    """The Welch PSD of the simulated series, in 8 log bands from the 4th bin up, lies within
    the 99.9 % chi-square interval of h * E (the exact expectation of each band at unit
    level), and the bands' whitened residuals have the chi-square spread."""
    samples, length = 2**17, 2**12
    frequency = laser_frequency_hz(samples, RATE_HZ, center_hz=CENTER_HZ, rng=7, **LEVELS[noise])
    window = get_window("hann", length)
    _, psd = welch(frequency, fs=RATE_HZ, window=window, noverlap=length // 2, detrend="linear")
    level = next(iter(LEVELS[noise].values()))
    expected = level * welch_expectation(window, RATE_HZ)[TERM[noise]]
    edges = np.unique(np.geomspace(4, length // 2, 9).astype(int))
    starts, widths = edges[:-1], np.diff(edges)
    segments = (samples - length) // (length // 2) + 1
    dof, correlation = band_covariance(window, length // 2, segments, starts, widths)
    band = np.add.reduceat(psd[: edges[-1]], starts) / widths
    band_expected = np.add.reduceat(expected[: edges[-1]], starts) / widths
    low = band_expected * chi2.ppf(0.0005, dof) / dof
    high = band_expected * chi2.ppf(0.9995, dof) / dof
    assert np.all((band >= low) & (band <= high)), band / band_expected
    z = (band / band_expected - 1) / np.sqrt(2 / dof)
    statistic = z @ np.linalg.solve(correlation, z)
    assert chi2.ppf(0.0005, z.size) < statistic < chi2.ppf(0.9995, z.size)


@pytest.mark.parametrize("noise", ["white", "random_walk"])
def test_allan_deviation_of_white_and_random_walk_matches_the_analytic_value(noise):
    """allantools' overlapping ADEV of the simulated fractional frequency, at octave taus
    with at least 10 record lengths, is within 10 % of the analytic value where 10 % is
    three of Greenhall's standard errors, and inside the 99.9 % interval everywhere."""
    import allantools

    samples = 2**17
    frequency = laser_frequency_hz(samples, RATE_HZ, center_hz=CENTER_HZ, rng=3, **LEVELS[noise])
    fractional = (frequency - frequency.mean()) / CENTER_HZ
    factors = 2 ** np.arange(int(np.log2(samples // 10)) + 1)
    taus, adev, _, _ = allantools.oadev(
        fractional, rate=RATE_HZ, data_type="freq", taus=factors / RATE_HZ
    )
    analytic = power_law_deviations(taus, CENTER_HZ, **LEVELS[noise])["adev"]
    alpha = 0 if noise == "white" else -2
    edf = np.array(
        [allantools.edf_greenhall(alpha, 2, int(m), samples + 1, overlapping=True) for m in factors]
    )
    ratio = adev / analytic
    precise = np.sqrt(1 / (2 * edf)) < 0.10 / 3  # the deviation's relative standard error
    assert precise.sum() >= 8
    assert np.all(np.abs(ratio[precise] - 1) < 0.10), ratio
    low, high = np.sqrt(chi2.ppf([0.0005, 0.9995], edf[:, None]) / edf[:, None]).T
    assert np.all((ratio >= low) & (ratio <= high)), ratio


@pytest.mark.slow
@pytest.mark.parametrize("noise", ["flicker", "random_walk"])
def test_regression_slope_variance_matches_the_simulated_spread(noise):
    """The variance of the least-squares slope of 400 simulated records agrees with
    slope_variance within its chi-square interval (99.9 %)."""
    samples, records = 2048, 400
    rng = np.random.default_rng(11)
    times = np.arange(samples) / RATE_HZ
    slopes = [
        np.polyfit(
            times,
            laser_frequency_hz(samples, RATE_HZ, center_hz=CENTER_HZ, rng=rng, **LEVELS[noise]),
            1,
        )[0]
        for _ in range(records)
    ]
    levels = np.zeros(3)
    levels[TERM[noise]] = next(iter(LEVELS[noise].values()))
    ratio = np.mean(np.square(slopes)) / slope_variance(samples, RATE_HZ, levels)
    assert chi2.ppf(0.0005, records) / records < ratio < chi2.ppf(0.9995, records) / records


def test_drift_is_exact_and_starts_at_the_center():
    frequency = laser_frequency_hz(1000, RATE_HZ, center_hz=CENTER_HZ, drift_hz_per_s=2e5)
    expected = CENTER_HZ + 2e5 * (np.arange(1000) + 0.5) / RATE_HZ
    np.testing.assert_allclose(frequency, expected, rtol=0, atol=1e-3)


def test_a_seed_reproduces_the_series_and_each_term_has_its_own_stream():
    kwargs = {"center_hz": CENTER_HZ, "rng": 5}
    both = laser_frequency_hz(4096, RATE_HZ, white_fm_hz2_per_hz=1e4, flicker_fm_hz2=1e8, **kwargs)
    np.testing.assert_array_equal(
        both,
        laser_frequency_hz(4096, RATE_HZ, white_fm_hz2_per_hz=1e4, flicker_fm_hz2=1e8, **kwargs),
    )
    white = laser_frequency_hz(4096, RATE_HZ, white_fm_hz2_per_hz=1e4, **kwargs)
    flicker = laser_frequency_hz(4096, RATE_HZ, flicker_fm_hz2=1e8, **kwargs)
    # float64 resolves 193 THz to 0.03 Hz
    np.testing.assert_allclose(
        both - CENTER_HZ, (white - CENTER_HZ) + (flicker - CENTER_HZ), atol=0.1
    )
    other = laser_frequency_hz(4096, RATE_HZ, white_fm_hz2_per_hz=1e4, center_hz=CENTER_HZ, rng=6)
    assert np.std(other - white) > 50  # two seeds: independent draws of std 71 Hz


def test_the_random_walk_starts_at_the_center_and_white_noise_has_its_variance():
    walk = laser_frequency_hz(
        10_000, RATE_HZ, center_hz=CENTER_HZ, random_walk_fm_hz2_per_s=1e11, rng=2
    )
    step_std = np.sqrt(2 * np.pi**2 * 1e11 / RATE_HZ)
    assert abs(walk[0] - CENTER_HZ) < 5 * step_std
    white = laser_frequency_hz(
        100_000, RATE_HZ, center_hz=CENTER_HZ, white_fm_hz2_per_hz=1e4, rng=2
    )
    variance_ratio = np.var(white) / (1e4 * RATE_HZ / 2)
    assert abs(variance_ratio - 1) < 5 * np.sqrt(2 / 100_000)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"samples": 0}, "samples"),
        ({"samples": 2.5}, "samples"),
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"rate_hz": float("nan")}, "rate_hz"),
        ({"center_hz": -1.0}, "center_hz"),
        ({"white_fm_hz2_per_hz": -1.0}, "white_fm_hz2_per_hz"),
        ({"flicker_fm_hz2": float("inf")}, "flicker_fm_hz2"),
        ({"random_walk_fm_hz2_per_s": "1"}, "random_walk_fm_hz2_per_s"),
        ({"drift_hz_per_s": float("nan")}, "drift_hz_per_s"),
        ({"rng": "seed"}, "rng"),
    ],
)
def test_bad_input_raises_an_input_error_naming_the_parameter(kwargs, name):
    arguments = {"samples": 100, "rate_hz": RATE_HZ, "center_hz": CENTER_HZ} | kwargs
    samples, rate = arguments.pop("samples"), arguments.pop("rate_hz")
    with pytest.raises(InputError, match=name):
        laser_frequency_hz(samples, rate, **arguments)
