"""The simulator over a wide band: dispersion, spectral slopes of the output coupler and the
responsivities, the silicon-nitride preset, and ``wavemeter simulate --spectral``."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.cli.simulate import SPECTRAL_PLATFORMS
from wavemeter.io import ColumnRequest, read_table
from wavemeter.simulation import SPECTRAL_PRESETS, Interferometer, SpectralPreset
from wavemeter.simulation.coupler_draws import symmetry_classes
from wavemeter.simulation.scenario_defaults import SPECTRAL_STREAM

from .helpers import NOISE_W, POWER_W, one_error, run_cli

EPS = np.finfo(float).eps
#: the issue's silicon-nitride numbers: dispersion (s^2), coupler slope sigma (symmetric,
#: breaking) and responsivity slope sigma (1/THz), and the delay the dispersion is of (s:
#: 50 GHz)
ISSUE_SIN = (4e-28, 0.01, 0.002, 0.005, 20e-12)
#: half the C band (Hz): 88 FSRs of 50 GHz about the centre
HALF_BAND_HZ = 2.2e12
SEED = 3


def _c_band_hz(device: Interferometer, samples: int = 2001) -> np.ndarray:
    """``samples`` frequencies (Hz) over the C band about the device centre."""
    return device.center_hz + np.linspace(-HALF_BAND_HZ, HALF_BAND_HZ, samples)


def _wide(ports: int = 4, seed: int = 7) -> Interferometer:
    """A Table 1 device with the silicon-nitride spectral preset (slopes from another seed)."""
    return Interferometer.table1(ports, seed=seed).with_spectral("sin", seed=seed + 100)


def _cli_device(seed: int, preset="sin") -> Interferometer:
    """The device ``wavemeter simulate --seed SEED`` simulates with a spectral preset."""
    rng = np.random.default_rng([seed, SPECTRAL_STREAM])
    return Interferometer.table1(3, seed=seed).with_spectral(preset, seed=rng)


# ---------------------------------------------------------------------------- slopes
def test_zero_slopes_give_the_readings_of_the_device_without_them():
    device = dataclasses.replace(Interferometer.table1(4, seed=7), dispersion_s2=4e-28)
    flat = dataclasses.replace(
        device,
        coupler_slope_per_thz=np.zeros((4, 4), complex),
        responsivity_slope_per_thz=np.zeros(4),
    )
    f = _c_band_hz(device)
    # the same noise draws: the zero slopes change nothing, not even a rounding
    np.testing.assert_array_equal(
        flat.powers(f, POWER_W, NOISE_W, rng=5), device.powers(f, POWER_W, NOISE_W, rng=5)
    )
    # one map per frequency, with or without slopes: the centre's
    for sloped in (flat, device):
        np.testing.assert_array_equal(
            sloped.true_map(frequency_hz=f), np.broadcast_to(device.true_map(), (f.size, 4, 3))
        )


def test_map_at_the_centre_is_true_map():
    device = _wide().with_thermal("sin")
    warm_k = device.reference_temperature_k + 3.0
    np.testing.assert_array_equal(device.true_map(frequency_hz=device.center_hz), device.true_map())
    np.testing.assert_array_equal(
        device.true_map(warm_k, frequency_hz=device.center_hz), device.true_map(warm_k)
    )
    assert device.true_map(frequency_hz=device.center_hz + 1e12).shape == (4, 3)
    # away from the centre the slopes move the map: by about 1 % per THz
    edge = device.true_map(frequency_hz=device.center_hz + HALF_BAND_HZ)
    assert np.abs(edge - device.true_map()).max() > 1e-3 * np.abs(device.true_map()).max()


@pytest.mark.parametrize("thermal", [False, True])
def test_readings_are_the_map_at_each_frequency_on_the_cone(thermal):
    device = _wide(5)
    temperature_k = None
    if thermal:
        device = device.with_thermal("soi")
        temperature_k = device.reference_temperature_k + np.linspace(-4, 4, 2001)
    f = _c_band_hz(device)
    maps = device.true_map(temperature_k, frequency_hz=f)
    assert maps.shape == (f.size, 5, 3)
    objects = wm.cone_vectors(device.phase_rad(f, temperature_k), POWER_W)
    expected_w = np.einsum("nkj,nj->nk", maps, objects)
    # the issue's 1e-12 (relative): the phase (up to 300 rad) rounds to 1e-13 rad at worst
    np.testing.assert_allclose(
        device.powers(f, POWER_W, temperature_k=temperature_k),
        expected_w,
        rtol=0,
        atol=1e-12 * POWER_W,
    )


def test_coupler_at_a_frequency_scales_real_and_imaginary_parts():
    device = Interferometer.table1(4, seed=2)
    slope = np.random.default_rng(9).normal(0, 0.02, (4, 4, 2)) @ np.array([1, 1j])
    sloped = dataclasses.replace(device, coupler_slope_per_thz=slope)
    for f_hz in device.center_hz + np.array([-2.1e12, 0.4e12, 1.7e12]):
        d = (f_hz - device.center_hz) / 1e12
        coupler = device.output_coupler
        at_f = coupler.real * (1 + slope.real * d) + 1j * coupler.imag * (1 + slope.imag * d)
        same = dataclasses.replace(device, output_coupler=at_f)
        # a few roundings of entries of size 1: eps-sized differences
        np.testing.assert_allclose(
            sloped.true_map(frequency_hz=f_hz), same.true_map(), rtol=0, atol=8 * EPS
        )


def test_responsivity_slope_scales_port_k_by_one_plus_slope_times_detuning():
    device = Interferometer.table1(4, seed=6)
    slope_per_thz = np.array([0.01, -0.02, 0.005, 0.0])
    sloped = dataclasses.replace(device, responsivity_slope_per_thz=slope_per_thz)
    f = _c_band_hz(device)
    d = (f - device.center_hz) / 1e12
    ratio = sloped.powers(f, POWER_W) / device.powers(f, POWER_W)
    # the factor 1 + s d is computed as here; the two readings and their ratio add at most
    # six roundings of eps / 2
    np.testing.assert_allclose(ratio, 1 + np.outer(d, slope_per_thz), rtol=3 * EPS, atol=0)
    np.testing.assert_array_equal(ratio[:, 3], 1.0)  # no slope: the same readings exactly


def test_a_responsivity_sloping_through_zero_is_refused():
    device = dataclasses.replace(
        Interferometer.table1(3, seed=6), responsivity_slope_per_thz=[0.0, 0.6, 0.0]
    )
    with pytest.raises(wm.InputError, match="responsivity of port 2 not positive"):
        device.powers(_c_band_hz(device))
    device.powers(device.sweep_hz(100))  # one FSR about the centre is fine


def test_slopes_are_validated_and_read_only():
    device = Interferometer.table1(3, seed=1)
    sloped = dataclasses.replace(
        device, coupler_slope_per_thz=np.ones((3, 3)), responsivity_slope_per_thz=[0.1, 0, 0]
    )
    assert sloped.coupler_slope_per_thz.dtype == complex
    assert not sloped.coupler_slope_per_thz.flags.writeable
    assert not sloped.responsivity_slope_per_thz.flags.writeable
    for name, bad in [
        ("coupler_slope_per_thz", np.ones((3, 2))),
        ("coupler_slope_per_thz", np.full((3, 3), np.nan)),
        ("responsivity_slope_per_thz", [0.1, 0.2]),
        ("responsivity_slope_per_thz", [0.1, np.inf, 0]),
        ("responsivity_slope_per_thz", ["a", "b", "c"]),
    ]:
        with pytest.raises(wm.InputError, match=name):
            dataclasses.replace(device, **{name: bad})


# ---------------------------------------------------------------------------- dispersion
def test_dispersion_bends_the_phase_by_the_formula():
    plain = Interferometer.table1(3, seed=4)
    bent = plain.with_spectral("sin", seed=1)
    dispersion_s2 = SPECTRAL_PRESETS["sin"].dispersion_s2
    assert bent.dispersion_s2 == dispersion_s2
    f = _c_band_hz(plain)
    w = 2 * np.pi * (f - plain.center_hz)
    # the phases (up to 280 rad) round to a few ulp of that
    np.testing.assert_allclose(
        bent.phase_rad(f) - plain.phase_rad(f), 0.5 * dispersion_s2 * w**2, rtol=0, atol=1e-13
    )
    expected_hz = 1 / (plain.delay_s + dispersion_s2 * w)
    np.testing.assert_allclose(bent.local_fsr_hz(f), expected_hz, rtol=4 * EPS)
    assert bent.true_fsr_hz == plain.true_fsr_hz == bent.local_fsr_hz(bent.center_hz)
    # the C band's edge: the local FSR of a 20 ps imbalance moves by 2.7e-4 of itself (the
    # preset's comment, to its two digits); this device's delay differs by Table 1's spread
    relative = bent.local_fsr_hz(f[[0, -1]]) / bent.true_fsr_hz - 1
    np.testing.assert_allclose(np.abs(relative), 2.7e-4 * 20e-12 / plain.delay_s, rtol=0.03)


def test_local_fsr_follows_the_temperature():
    device = Interferometer.table1(3, seed=4).with_thermal("soi")
    warm_k = device.reference_temperature_k + 5
    f = _c_band_hz(device, 5)
    np.testing.assert_allclose(device.local_fsr_hz(f, warm_k), device.true_fsr_hz_at(warm_k))


# ---------------------------------------------------------------------------- preset
def test_preset_has_the_issues_silicon_nitride_values():
    preset = SPECTRAL_PRESETS["sin"]
    assert dataclasses.astuple(preset) == ISSUE_SIN
    assert set(SPECTRAL_PRESETS) == set(SPECTRAL_PLATFORMS)
    with pytest.raises(TypeError):
        SPECTRAL_PRESETS["soi"] = preset
    with pytest.raises(wm.InputError, match="coupler_slope_sigma_per_thz"):
        SpectralPreset(0.0, -0.01, 0.0, 0.0)
    with pytest.raises(wm.InputError, match="dispersion_s2"):
        SpectralPreset(np.nan, 0.01, 0.0, 0.0)
    with pytest.raises(wm.InputError, match="platform must be one of"):
        Interferometer.table1(3).with_spectral("soi")


def test_preset_draws_reproducible_slopes_and_keeps_the_rest():
    device = Interferometer.table1(4, seed=2)
    a, b, c = (device.with_spectral("sin", seed=seed) for seed in (11, 11, 12))
    for name in ("coupler_slope_per_thz", "responsivity_slope_per_thz"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert not np.any(getattr(a, name) == getattr(c, name)), name
    spectral = {"dispersion_s2", "coupler_slope_per_thz", "responsivity_slope_per_thz"}
    for field in dataclasses.fields(Interferometer):
        if field.name not in spectral:
            assert np.array_equal(getattr(a, field.name), getattr(device, field.name)), field.name


def test_coupler_slopes_follow_the_mmi_symmetry_and_their_sigmas():
    """Many ports, many seeds: the sample spread of each part within 4 standard errors.

    The standard error of a sample standard deviation of ``k`` normal draws is
    ``sigma / sqrt(2 k)``.
    """
    ports, seeds = 16, range(10)
    device = Interferometer.table1(ports, seed=1)
    labels = symmetry_classes(ports)
    first = np.unique(labels, return_index=True)[1]  # one entry of each orbit
    symmetric = SpectralPreset(0.0, 0.03, 0.0, 0.0)
    shared = []
    for seed in seeds:
        slope = device.with_spectral(symmetric, seed=seed).coupler_slope_per_thz
        # entries one symmetry maps onto another share their slope exactly
        np.testing.assert_array_equal(slope, slope.flat[first][labels])
        shared += [slope.real.flat[first], slope.imag.flat[first]]
    breaking = SpectralPreset(0.0, 0.0, 0.002, 0.004)
    drawn = [device.with_spectral(breaking, seed=seed) for seed in seeds]
    own = [d.coupler_slope_per_thz.real for d in drawn] + [
        d.coupler_slope_per_thz.imag for d in drawn
    ]
    responsivity = [d.responsivity_slope_per_thz for d in drawn]
    for values, sigma in [(shared, 0.03), (own, 0.002), (responsivity, 0.004)]:
        values = np.concatenate([np.ravel(v) for v in values])
        assert np.std(values) == pytest.approx(sigma, rel=4 / np.sqrt(2 * values.size))


# ---------------------------------------------------------------------------- command line
def _simulate(capsys, path, options: str) -> str:
    code, printed, err = run_cli(capsys, f"simulate -o {path} --seed {SEED} {options}")
    assert code == 0, err
    return printed


def _read(path):
    return read_table(path, ColumnRequest(x="frequency_hz"))


def test_cli_spectral_sweep_is_the_librarys_device(capsys, tmp_path):
    sweep = tmp_path / "band.npz"
    printed = _simulate(capsys, sweep, "--spectral sin --span-fsr 4 --samples 800")
    device = _cli_device(SEED)
    table = _read(sweep)
    np.testing.assert_array_equal(table.x_hz, device.sweep_hz(800, 4.0))
    # the Table 1 device, the slopes of the seed's spectral stream, the seed's noise
    expected_w = device.powers(table.x_hz, POWER_W, NOISE_W, rng=np.random.default_rng(SEED))
    np.testing.assert_array_equal(table.powers_w, expected_w)
    assert "spectral: sin, dispersion 4e-28 s^2" in printed
    # the test file too (noiseless, so that its readings are the device's at its frequencies)
    _simulate(
        capsys, sweep, "--spectral sin --span-fsr 4 --samples 800 --test 300 --noise 0 --force"
    )
    test = read_table(tmp_path / "band-test.npz", ColumnRequest(x="true_frequency_hz"))
    np.testing.assert_array_equal(test.powers_w, device.powers(test.x_hz, POWER_W))


def test_cli_slope_options_replace_the_presets(capsys, tmp_path):
    options = "--dispersion 1e-27 --coupler-slope 0.03 --responsivity-slope 0 --noise 0"
    cases = [
        (f"--spectral sin {options}", SpectralPreset(1e-27, 0.03, 0.002, 0.0)),
        ("--coupler-slope 0.02 --noise 0", SpectralPreset(0.0, 0.02, 0.0, 0.0)),
    ]
    tables = []
    for index, (given, preset) in enumerate(cases):
        sweep = tmp_path / f"s{index}.npz"
        _simulate(capsys, sweep, f"--span-fsr 20 --samples 400 {given}")
        tables.append(_read(sweep))
        expected_w = _cli_device(SEED, preset).powers(tables[-1].x_hz, POWER_W)
        np.testing.assert_array_equal(tables[-1].powers_w, expected_w)
    # the coupler slopes alone do reach the readings: about 1 % at 0.5 THz from the centre
    plain = tmp_path / "plain.npz"
    _simulate(capsys, plain, "--span-fsr 20 --samples 400 --noise 0")
    assert np.abs(_read(plain).powers_w - tables[1].powers_w).max() > 1e-3 * POWER_W


def test_cli_c_band_sweep(capsys, tmp_path):
    sweep = tmp_path / "band.npz"
    printed = _simulate(capsys, sweep, "--spectral sin --span-fsr 88 --samples 176000")
    table = _read(sweep)
    device = _cli_device(SEED)
    assert table.n_rows == 176000
    span_hz = table.x_hz[-1] - table.x_hz[0]
    assert span_hz == pytest.approx(88 * device.true_fsr_hz * (1 - 1 / 176000), rel=1e-12)
    low, high = (f"{device.local_fsr_hz(f) / 1e9:.6f} GHz" for f in table.x_hz[[0, -1]])
    assert f"local FSR {low} at the sweep's low end, {high} at its high end" in printed
    centre_hz = 0.5 * (table.x_hz[0] + table.x_hz[-1])
    fringe = f"{device.fringe_fsr_hz(centre_hz)[0] / 1e9:.6f} GHz"
    assert f"the fringes' {fringe} at its centre" in printed


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ("--spectral soi", "'soi' is not 'sin'"),
        ("--coupler-slope -0.01", "-0.01: must be >= 0"),
        ("--responsivity-slope nan", "nan is not a finite number"),
        ("--responsivity-slope 1%", "'1%' is not a valid float"),
        ("--dispersion inf", "inf is not a finite number"),
        (
            "--responsivity-slope 10 --span-fsr 88",
            "responsivity_slope_per_thz makes the responsivity of port",
        ),
    ],
)
def test_cli_bad_spectral_values(capsys, tmp_path, options, expected):
    out = tmp_path / "s.csv"
    err = one_error(*run_cli(capsys, f"simulate -o {out} --samples 1000 {options}")[::2])
    assert expected in err and not out.exists()
