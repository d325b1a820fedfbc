"""Hardware faults of the simulator: dark offsets, dispersion, per-port noise, drifts, CLI."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.simulation import (
    Interferometer,
    flicker_power_noise,
    slow_power_drift,
    thermal_ramp_rad,
)
from wavemeter.simulation.drift import DRIFT_HARMONICS

from .helpers import NOISE_W, POWER_W, one_error, run_cli

EPS = np.finfo(float).eps
#: rounding of a sum of readings of about POWER_W (W): a few ulp
ROUNDING_W = 8 * EPS * POWER_W


@pytest.fixture
def device() -> Interferometer:
    return Interferometer.table1(3, seed=4)


# ---------------------------------------------------------------------------- dark offset
def test_dark_offset_adds_to_every_reading_before_the_noise(device):
    offset_w = np.array([2e-6, 0.0, -5e-7])
    dark = dataclasses.replace(device, dark_offset_w=offset_w)
    f = device.sweep_hz(300)
    power_w = np.linspace(0.5e-3, 1.5e-3, f.size)
    # the same seed, the same noise draws: the offset is all that differs
    difference = dark.powers(f, power_w, NOISE_W, rng=3) - device.powers(f, power_w, NOISE_W, 3)
    np.testing.assert_allclose(
        difference, np.broadcast_to(offset_w, f.shape + (3,)), atol=ROUNDING_W
    )
    # independent of the source power: in the dark the reading is the offset exactly
    np.testing.assert_array_equal(dark.powers(f, 0.0), np.broadcast_to(offset_w, (f.size, 3)))
    np.testing.assert_array_equal(dark.true_map(), device.true_map())


def test_dark_offset_is_validated_and_read_only(device):
    dark = dataclasses.replace(device, dark_offset_w=[1e-6, 2e-6, 3e-6])
    assert dark.dark_offset_w.dtype == float and not dark.dark_offset_w.flags.writeable
    for bad in ([1e-6, 2e-6], [1e-6, np.nan, 0.0], np.zeros((3, 1))):
        with pytest.raises(wm.InputError, match="dark_offset_w must be 3 finite numbers"):
            dataclasses.replace(device, dark_offset_w=bad)


# ---------------------------------------------------------------------------- dispersion
def test_dispersion_bends_the_phase_and_the_local_fsr(device):
    # the group delay changes by 10 % over one FSR either side of the centre
    dispersion_s2 = 0.1 * device.delay_s / (2 * np.pi * device.true_fsr_hz)
    bent = dataclasses.replace(device, dispersion_s2=dispersion_s2)
    assert bent.true_fsr_hz == device.true_fsr_hz == 1 / device.delay_s
    f = device.center_hz + device.true_fsr_hz * np.linspace(-1.0, 1.0, 9)
    step_hz = 1e8
    upper, lower = f + step_hz, f - step_hz
    # the central difference of a quadratic phase is exact but for rounding: the phase
    # (|t| <= 2.2 pi) is rounded to ~eps |t|, the step is 2 pi tau 2e8 ~ 0.025 rad
    slope = (bent.phase_rad(upper) - bent.phase_rad(lower)) / (upper - lower)
    local_fsr_hz = 2 * np.pi / slope
    expected_hz = 1 / (device.delay_s + dispersion_s2 * 2 * np.pi * (f - device.center_hz))
    np.testing.assert_allclose(local_fsr_hz, expected_hz, rtol=1e-11)
    np.testing.assert_allclose(1 / bent.group_delay_s(f), expected_hz, rtol=1e-14)
    assert np.ptp(expected_hz) / device.true_fsr_hz > 0.15  # the test sees the dispersion
    # the readings follow the bent phase: the clean map applied to the cone at phase t
    detuning = 2 * np.pi * (f - device.center_hz)
    phase_rad = detuning * device.delay_s + 0.5 * dispersion_s2 * detuning**2
    expected_w = wm.cone_vectors(phase_rad, POWER_W) @ device.true_map().T
    np.testing.assert_allclose(bent.powers(f, POWER_W), expected_w, atol=1e-18)


def test_dispersion_must_be_finite(device):
    with pytest.raises(wm.InputError, match="dispersion_s2"):
        dataclasses.replace(device, dispersion_s2=np.inf)


# ---------------------------------------------------------------------------- noise per port
def test_per_port_noise_has_each_ports_standard_deviation(device):
    f = np.full(20000, device.center_hz)
    noise_w = np.array([1e-7, 5e-7, 2e-6])
    clean = device.powers(f, POWER_W)
    spread_w = np.std(device.powers(f, POWER_W, noise_w, rng=11) - clean, axis=0)
    # the sample std of 20000 Gaussian draws has relative standard error 1/sqrt(2N) = 0.5 %:
    # within 5 standard errors
    np.testing.assert_allclose(spread_w, noise_w, rtol=5 / np.sqrt(2 * f.size))
    # one value for every port is the scalar noise, draw for draw
    np.testing.assert_array_equal(
        device.powers(f[:50], POWER_W, np.full(3, NOISE_W), rng=2),
        device.powers(f[:50], POWER_W, NOISE_W, rng=2),
    )
    # a noiseless port stays clean
    quiet_port = device.powers(f, POWER_W, np.array([0.0, 1e-6, 1e-6]), rng=3)
    np.testing.assert_array_equal(quiet_port[:, 0], clean[:, 0])


@pytest.mark.parametrize("noise_w", [[1e-7, 1e-7], [1e-7, -1e-7, 0.0], [np.nan] * 3, np.inf])
def test_bad_per_port_noise_is_refused(device, noise_w):
    with pytest.raises(wm.InputError, match="noise_w"):
        device.powers([device.center_hz], noise_w=noise_w)


# ---------------------------------------------------------------------------- bias drift
def test_bias_drift_is_the_clean_device_at_a_shifted_bias(device):
    f = device.sweep_hz(40)
    drift_rad = np.linspace(-2.0, 3.0, f.size)
    drifted = device.powers(f, POWER_W, bias_drift_rad=drift_rad)
    for k in (0, 7, 23, 39):
        shifted = dataclasses.replace(device, bias_phase_rad=device.bias_phase_rad + drift_rad[k])
        np.testing.assert_allclose(drifted[k], shifted.powers(f[k : k + 1], POWER_W)[0], atol=1e-17)
    constant = device.powers(f, POWER_W, bias_drift_rad=0.4)
    shifted = dataclasses.replace(device, bias_phase_rad=device.bias_phase_rad + 0.4)
    np.testing.assert_allclose(constant, shifted.powers(f, POWER_W), atol=1e-17)
    with pytest.raises(wm.InputError, match="bias_drift_rad"):
        device.powers(f, bias_drift_rad=np.zeros(f.size + 1))


def test_thermal_ramp_is_a_temperature_ramp(device):
    hot = dataclasses.replace(device, thermal_phase_rad_per_k=0.3)
    f = device.sweep_hz(64)
    ramp_rad = thermal_ramp_rad(f.size, 2.0, hot.thermal_phase_rad_per_k)
    temperature_k = hot.reference_temperature_k + np.linspace(0.0, 2.0, f.size)
    np.testing.assert_allclose(
        hot.powers(f, POWER_W, bias_drift_rad=ramp_rad),
        hot.powers(f, POWER_W, temperature_k=temperature_k),
        atol=1e-17,
    )


def test_thermal_shapes():
    ramp = thermal_ramp_rad(101, -1.5, 0.2)
    assert ramp.shape == (101,) and ramp[0] == 0.0
    assert ramp[-1] == pytest.approx(-0.3, rel=1e-15)
    np.testing.assert_allclose(np.diff(ramp, 2), 0.0, atol=4 * EPS * 0.3)  # linear, to rounding
    cycle = thermal_ramp_rad(400, 2.0, 0.5, shape="cycle", cycles=2.0)
    assert cycle.max() == pytest.approx(0.5, rel=1e-15)  # peak-to-peak 2 K at 0.5 rad/K
    assert cycle.min() == pytest.approx(-0.5, rel=1e-15)
    np.testing.assert_allclose(cycle[:200], cycle[200:], atol=1e-15)  # two periods
    with pytest.raises(wm.InputError, match="shape"):
        thermal_ramp_rad(10, 1.0, 1.0, shape="step")
    with pytest.raises(wm.InputError, match="total_k"):
        thermal_ramp_rad(10, np.nan, 1.0)


# ---------------------------------------------------------------------------- drift series
def test_slow_power_drift_is_a_few_slow_harmonics_with_peak_amplitude():
    samples, amplitude, cycles = 1000, 0.2, 3.0
    factor = slow_power_drift(samples, amplitude, rng=5, cycles=cycles)
    assert factor.shape == (samples,) and factor.min() > 0
    assert np.abs(factor - 1).max() == pytest.approx(amplitude, rel=1e-14)
    # it lies exactly in the span of the documented harmonics (periods up to `cycles`)
    u = np.arange(samples) / samples
    angle = 2 * np.pi * np.outer(u, cycles * np.arange(1, DRIFT_HARMONICS + 1) / DRIFT_HARMONICS)
    basis = np.column_stack([np.ones(samples), np.cos(angle), np.sin(angle)])
    coefficients = np.linalg.lstsq(basis, factor, rcond=None)[0]
    np.testing.assert_allclose(basis @ coefficients, factor, atol=1e-12)
    np.testing.assert_array_equal(factor, slow_power_drift(samples, amplitude, rng=5, cycles=3.0))
    other = slow_power_drift(samples, amplitude, rng=np.random.default_rng(6), cycles=3.0)
    assert not np.allclose(factor, other)
    np.testing.assert_array_equal(slow_power_drift(50, 0.0, rng=1), np.ones(50))


@pytest.mark.parametrize(
    ("arguments", "match"),
    [
        ((100, 1.0), "relative_amplitude"),
        ((100, -0.1), "relative_amplitude"),
        ((100, np.nan), "relative_amplitude"),
        ((0, 0.1), "samples"),
        ((True, 0.1), "samples"),
    ],
)
def test_slow_power_drift_refuses_bad_values(arguments, match):
    with pytest.raises(wm.InputError, match=match):
        slow_power_drift(*arguments)
    with pytest.raises(wm.InputError, match="cycles"):
        slow_power_drift(100, 0.1, cycles=0.0)


def test_flicker_noise_is_reproducible_with_unit_spread():
    factor = flicker_power_noise(5000, 0.02, rng=8)
    assert factor.shape == (5000,) and factor.min() > 0
    assert factor.mean() == pytest.approx(1.0, abs=1e-15)
    assert factor.std() == pytest.approx(0.02, rel=1e-12)
    np.testing.assert_array_equal(factor, flicker_power_noise(5000, 0.02, rng=8))
    assert not np.array_equal(factor, flicker_power_noise(5000, 0.02, rng=9))
    with pytest.raises(wm.InputError, match="relative_std .* takes the source power to <= 0"):
        flicker_power_noise(5000, 1.0, rng=8)  # 5000 unit-variance samples reach below -1
    with pytest.raises(wm.InputError, match="relative_std"):
        flicker_power_noise(100, -0.1)


def test_flicker_noise_spectrum_falls_as_one_over_f():
    """Log-log slope of the mean periodogram over a decade of frequency: -1.

    The periodogram of ``M`` independent series, averaged, scatters by ``1/sqrt(M)`` in
    log per frequency bin (chi-square with 2M degrees of freedom); the least-squares slope
    over the bins of a decade then has the standard error ``sigma / sqrt(sum (x - x_mean)^2)``
    with ``x = ln f``. The slope must be within 4 of those of -1.
    """
    series, samples = 64, 4096
    rng = np.random.default_rng(20261122)
    spectra = [
        np.abs(np.fft.rfft(flicker_power_noise(samples, 0.01, rng) - 1)) ** 2 for _ in range(series)
    ]
    mean_spectrum = np.mean(spectra, axis=0)
    frequency = np.fft.rfftfreq(samples)
    band = (frequency >= 0.01) & (frequency <= 0.1)
    x, y = np.log(frequency[band]), np.log(mean_spectrum[band])
    slope = np.polyfit(x, y, 1)[0]
    standard_error = (1 / np.sqrt(series)) / np.sqrt(np.sum((x - x.mean()) ** 2))
    assert abs(slope + 1) < 4 * standard_error, (slope, standard_error)
    assert 4 * standard_error < 0.1  # the test would see a white (0) or red (-2) spectrum


# ---------------------------------------------------------------------------- command line
def _table(path) -> dict[str, np.ndarray]:
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: data[name] for name in data.dtype.names}


def _ports(table) -> np.ndarray:
    return np.column_stack([table[f"p{k}_w"] for k in (1, 2, 3)])


def _simulate(capsys, folder, name, options=""):
    sweep = folder / f"{name}.csv"
    command = f"simulate -o {sweep} --samples 200 --test 50 --seed 3 --quiet {options}"
    code, _, err = run_cli(capsys, command)
    assert code == 0, err
    return _table(sweep), _table(folder / f"{name}-test.csv")


@pytest.fixture
def clean(capsys, tmp_path):
    return _simulate(capsys, tmp_path, "clean")


@pytest.fixture
def noiseless(capsys, tmp_path):
    return _simulate(capsys, tmp_path, "noiseless", "--noise 0")


def test_cli_dark_offset_shifts_both_files(capsys, tmp_path, clean):
    for option, offset_w in [("2uW", np.full(3, 2e-6)), ("'1e-7,0,-5e-8'", [1e-7, 0, -5e-8])]:
        sweep, test = _simulate(capsys, tmp_path, "dark", f"--dark-offset {option} --force")
        for faulty, reference in ((sweep, clean[0]), (test, clean[1])):
            assert list(faulty) == list(reference)  # no new column
            difference = _ports(faulty) - _ports(reference)
            np.testing.assert_allclose(
                difference, np.broadcast_to(offset_w, difference.shape), atol=ROUNDING_W
            )


def test_cli_port_noise(capsys, tmp_path, clean, noiseless):
    same = _simulate(capsys, tmp_path, "same", "--port-noise 5e-7,5e-7,5e-7")
    for faulty, reference in zip(same, clean, strict=True):
        np.testing.assert_array_equal(_ports(faulty), _ports(reference))  # draw for draw
    noise_w = np.array([1e-7, 1e-6, 4e-6])
    sweep, test = _simulate(capsys, tmp_path, "ports", "--port-noise '0.1uW,1uW,4uW'")
    spread_w = np.std(_ports(sweep) - _ports(noiseless[0]), axis=0)
    # 200 draws per port: relative standard error 1/sqrt(400) = 5 %; within 4 of them
    np.testing.assert_allclose(spread_w, noise_w, rtol=4 / np.sqrt(2 * 200))
    assert np.std(_ports(test) - _ports(noiseless[1]), axis=0)[2] > 1e-6  # the test file too


def test_cli_dispersion_bends_sweep_and_test(capsys, tmp_path, noiseless):
    dispersion_s2 = 5e-24
    device = dataclasses.replace(Interferometer.table1(3, seed=3), dispersion_s2=dispersion_s2)
    for table, axis in zip(
        _simulate(capsys, tmp_path, "dispersion", f"--dispersion {dispersion_s2} --noise 0"),
        ("frequency_hz", "true_frequency_hz"),
        strict=True,
    ):
        expected_w = device.powers(table[axis], POWER_W)
        np.testing.assert_allclose(_ports(table), expected_w, atol=ROUNDING_W)
    assert np.abs(_ports(table) - _ports(noiseless[1])).max() > 1e3 * ROUNDING_W


def test_cli_power_drift_moves_the_sweep_and_the_monitor_records_it(capsys, tmp_path, noiseless):
    sweep, test = _simulate(capsys, tmp_path, "drift", "--power-drift 0.1 --noise 0")
    device = Interferometer.table1(3, seed=3)
    power_w = sweep["monitor_w"] / device.monitor_ratio
    assert np.abs(power_w / POWER_W - 1).max() == pytest.approx(0.1, rel=1e-12)
    ratio = _ports(sweep) / _ports(noiseless[0])
    np.testing.assert_allclose(ratio, np.broadcast_to((power_w / POWER_W)[:, None], ratio.shape))
    # the test file has no drift: its readings are the clean ones, its monitor constant
    np.testing.assert_array_equal(_ports(test), _ports(noiseless[1]))
    np.testing.assert_allclose(test["monitor_w"], device.monitor_ratio * POWER_W, rtol=1e-15)
    # the drift has its own random stream: with noise, only the drift differs
    noisy, _ = _simulate(capsys, tmp_path, "noisy", "--power-drift 0.1")
    no_monitor, _ = _simulate(capsys, tmp_path, "bare", "--power-drift 0.1 --no-monitor")
    assert "monitor_w" not in no_monitor
    np.testing.assert_array_equal(_ports(no_monitor), _ports(noisy))
    noise_w = _ports(noisy) - _ports(sweep)
    assert np.std(noise_w) == pytest.approx(NOISE_W, rel=4 / np.sqrt(2 * noise_w.size))
    clean_noise_w = _ports(_simulate(capsys, tmp_path, "again")[0]) - _ports(noiseless[0])
    np.testing.assert_allclose(noise_w, clean_noise_w, atol=ROUNDING_W)


def test_cli_thermal_drift_ramps_the_bias_in_the_sweep_only(capsys, tmp_path, noiseless):
    sweep, test = _simulate(capsys, tmp_path, "warm", "--thermal-drift 0.5 --noise 0")
    # a Table 1 device has no thermal coefficient: the CLI uses 1 rad/K
    device = dataclasses.replace(Interferometer.table1(3, seed=3), thermal_phase_rad_per_k=1.0)
    temperature_k = device.reference_temperature_k + np.linspace(0, 0.5, sweep["frequency_hz"].size)
    expected_w = device.powers(sweep["frequency_hz"], POWER_W, temperature_k=temperature_k)
    np.testing.assert_allclose(_ports(sweep), expected_w, atol=ROUNDING_W)
    np.testing.assert_array_equal(_ports(test), _ports(noiseless[1]))
    assert "monitor_w" not in sweep


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--dark-offset 1uW,2uW", "--dark-offset has 2 value(s) for 3 ports"),
        ("--dark-offset 1mA", "unknown power unit 'mA'"),
        ("--port-noise 1e-7,-1e-7,0", "each must be >= 0"),
        ("--port-noise 1e-7", "--port-noise has 1 value(s) for 3 ports: give 3"),
        ("--port-noise 1e-7,1e-7,1e-7 --noise 1e-7", "give --noise (every port) or --port-noise"),
        ("--dispersion nan", "nan is not a finite number"),
        ("--dispersion 1ps", "'1ps' is not a valid float"),
        ("--power-drift 1", "1: must be in [0, 1)"),
        ("--power-drift -0.2", "-0.2: must be in [0, 1)"),
        ("--thermal-drift inf", "inf is not a finite number"),
    ],
)
def test_cli_bad_fault_values(capsys, tmp_path, options, expected):
    out = tmp_path / "s.csv"
    err = one_error(*run_cli(capsys, f"simulate -o {out} --samples 10 {options}")[::2])
    assert expected in err and not out.exists()
