"""The one-pass reading of a live stream against the batch methods it stands in for.

``BaseCalibrator.stream`` reads a calibration of the learned family (and a thermal one) in
one pass per reading, and a cascade stage by stage with ``StageReader``; ``stream_lines``
converts a plain line without ``convert_rows``. Each must give the numbers of ``predict``,
``frequency_std_hz``, ``flags`` (and a cascade's ``read``) and of the file readers, to float64
rounding (``RTOL``: the same arithmetic on one reading instead of a batch, or written out
for one reading, rounds differently in the last bits; measured ~1e-14), the flags bit for bit.
The readings are chosen so that every flag bit these calibrations give occurs, and the
``OFF_MODEL`` screen is tested where it must give way to the exact test: readings at the
threshold itself.
"""

from __future__ import annotations

import io
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.methods.cascade_reading import (
    MIN_SCALED_READINGS,
    NOISE_P_VALUE,
    StageReader,
    noise_scale,
)
from wavemeter.io import read_table
from wavemeter.io.convert import convert_rows
from wavemeter.jobs import stream, stream_lines

from .helpers import NOISE_W, POWER_W, thermal_sweep

RTOL = 1e-12
FLAG = wm.ReadingFlag


def _fitted(estimator, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return estimator.fit(*args, **kwargs)


def assert_streams_its_numbers(cal, rows, **inputs):
    """The records of ``cal.stream(rows)`` against predict, frequency_std_hz and flags."""
    streamed = {name: iter(values) for name, values in inputs.items()}
    records = list(cal.stream(rows, **streamed))
    found = {
        name: np.array([getattr(record, name) for record in records])
        for name in ("frequency_hz", "frequency_std_hz", "flags")
    }
    np.testing.assert_allclose(found["frequency_hz"], cal.predict(rows, **inputs), rtol=RTOL)
    np.testing.assert_allclose(
        found["frequency_std_hz"], cal.frequency_std_hz(rows, **inputs), rtol=RTOL
    )
    np.testing.assert_array_equal(found["flags"], cal.flags(rows, **inputs))
    return found["flags"]


def all_bits(flags) -> int:
    return int(np.bitwise_or.reduce(flags))


# ---------------------------------------------------------------------------- learned family
@pytest.fixture(scope="module")
def device() -> wm.Interferometer:
    return wm.Interferometer.table1(3, seed=7)


def flagged_readings(device, rng) -> np.ndarray:
    """Readings over the whole FSR (beyond a partial sweep), one at 3x the power, one with a
    port 20 % off, one too dark to trust."""
    frequency = device.center_hz + rng.uniform(-0.5, 0.5, 60) * device.true_fsr_hz
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=rng)
    return np.vstack(
        [powers, 3.0 * powers[0], powers[1] * np.array([1.2, 1.0, 1.0]), 1e-4 * powers[2]]
    )


@pytest.mark.parametrize(
    "case", ["partial span", "partial span, ml retrieval", "dark offsets", "whole fsr"]
)
def test_the_learned_family_streams_the_numbers_of_its_batch_methods(device, case):
    span = 1.0 if case == "whole fsr" else 0.6
    sweep_hz = device.sweep_hz(300, span_fsr=span)
    dark_w = np.array([2e-6, -1e-6, 3e-6]) if case == "dark offsets" else None
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=1) + (0.0 if dark_w is None else dark_w)
    retrieval = "ml" if "ml" in case else "pinv"
    cal = _fitted(wm.Calibrator(fsr_hz=50e9, retrieval=retrieval), sweep, sweep_hz, dark_w=dark_w)
    rows = flagged_readings(device, np.random.default_rng(3))
    if dark_w is not None:
        rows = rows + dark_w
    bits = all_bits(assert_streams_its_numbers(cal, rows))
    expected = FLAG.OFF_MODEL | FLAG.POWER_RANGE | FLAG.INVALID
    if span < 1.0:
        expected |= FLAG.OUTSIDE_SPAN
    assert bits & expected == expected


def test_the_off_model_screen_gives_way_to_the_test_at_its_threshold(device, monkeypatch):
    """Readings moved off the cone by amounts about the one the exact test flags at: the
    bound at the retrieved phase exceeds the threshold before the distance does, so there
    the exact test decides; clean readings never reach it."""
    sweep_hz = device.sweep_hz(300)
    cal = _fitted(
        wm.Calibrator(fsr_hz=50e9), device.powers(sweep_hz, POWER_W, NOISE_W, rng=1), sweep_hz
    )
    clean = device.powers(device.center_hz + 0.2 * device.true_fsr_hz, POWER_W, 0.0)
    direction = np.array([1.0, -0.3, 0.1]) * POWER_W

    def off_model(amount: float) -> bool:
        return bool(cal.flags(clean + amount * direction)[0] & FLAG.OFF_MODEL)

    low, high = 0.0, 0.5  # not flagged, flagged: the threshold's amount between, by bisection
    assert not off_model(low) and off_model(high)
    for _ in range(60):
        middle = 0.5 * (low + high)
        low, high = (low, middle) if off_model(middle) else (middle, high)
    amounts = high * np.array([0.5, 0.9, 0.99, 0.999, 1.0 - 1e-9, 1.0, 1.001, 1.01, 1.1])
    rows = clean + amounts[:, None] * direction
    calls = []
    exact = cal._off_model
    monkeypatch.setattr(cal, "_off_model", lambda *args: calls.append(1) or exact(*args))
    flags = assert_streams_its_numbers(cal, rows)
    assert [bool(bit) for bit in flags & FLAG.OFF_MODEL] == [False] * 5 + [True] * 4
    # beside the one call of flags() above: the flagged rows and some of the others, at
    # the threshold, took the exact test; the screen cleared the rest
    assert 4 < len(calls) - 1 < rows.shape[0]
    calls.clear()
    noisy = device.powers(device.sweep_hz(50), POWER_W, NOISE_W, rng=4)
    list(cal.stream(noisy))
    assert calls == []  # readings on the model never take the exact test


def test_a_thermal_calibration_streams_its_numbers_and_temperature_flags(device):
    thermal_device = device.with_thermal("sin")
    powers, frequency, temperature = thermal_sweep(thermal_device, 150, NOISE_W, 1)
    cal = _fitted(wm.ThermalCalibrator(), powers, frequency, temperature_k=temperature)
    rng = np.random.default_rng(8)
    kelvin = rng.uniform(285.0, 302.0, 40)  # beyond the calibrated 289-297 K on both sides
    truth = device.center_hz + rng.uniform(-0.5, 0.5, 40) * device.true_fsr_hz
    rows = np.vstack(
        [
            thermal_device.powers([f], POWER_W, NOISE_W, rng=rng, temperature_k=t)
            for f, t in zip(truth, kelvin, strict=True)
        ]
    )
    bits = all_bits(assert_streams_its_numbers(cal, rows, temperature_k=kelvin))
    assert bits & FLAG.TEMPERATURE_RANGE


@pytest.mark.parametrize("case", ["pinv", "ml", "thermal"])
def test_a_learned_residual_streams_the_flags_of_its_batch_methods(device, case):
    """Detectors that compress by 5 % at the sweep's largest reading: the fit learns the
    residual the sweep's readings share and tests what remains at the retrieved phase (no
    screen); the stream gives the numbers and flags of the batch methods, on good readings
    and on readings glitched about the threshold."""
    thermal = device.with_thermal("sin")
    if case == "thermal":
        powers, frequency, temperature = thermal_sweep(thermal, 150, NOISE_W, 1)
    else:
        frequency = device.sweep_hz(600)
        powers, temperature = device.powers(frequency, POWER_W, NOISE_W, rng=1), None
    largest = float(powers.max())
    squeezed = powers - 0.05 * powers**2 / largest
    if case == "thermal":
        cal = _fitted(wm.ThermalCalibrator(), squeezed, frequency, temperature_k=temperature)
    else:
        cal = _fitted(wm.Calibrator(fsr_hz=50e9, retrieval=case), squeezed, frequency)
    assert cal.off_model_basis_.residual is not None
    rng = np.random.default_rng(12)
    truth = device.center_hz + rng.uniform(-0.5, 0.5, 60) * device.true_fsr_hz
    kelvin = rng.uniform(290.0, 296.0, truth.size)
    rows = np.vstack(
        [
            thermal.powers([f], POWER_W, NOISE_W, rng=rng, temperature_k=t)
            if case == "thermal"
            else device.powers([f], POWER_W, NOISE_W, rng=rng)
            for f, t in zip(truth, kelvin, strict=True)
        ]
    )
    rows = rows - 0.05 * rows**2 / largest
    steps = np.linspace(0.0, 40.0, 20)[:, None] * NOISE_W * np.array([1.0, -0.5, 0.2])
    rows = np.vstack([rows, rows[:20] + steps])
    inputs = {"temperature_k": np.concatenate([kelvin, kelvin[:20]])} if case == "thermal" else {}
    flags = assert_streams_its_numbers(cal, rows, **inputs)
    assert 0 < np.count_nonzero(flags[-20:] & FLAG.OFF_MODEL) < 20


# ---------------------------------------------------------------------------- cascade
@pytest.fixture(scope="module", params=["plain", "offsets fitted", "dark offsets"])
def cascade(request):
    """The issue's C-band cascade (phase polynomials to order 4, maps to order 2), swept at
    a steady power, at a varying one with a monitor (offsets fitted: a column of ones in
    each stage's covariance), or with dark readings to subtract; readings across its band
    and a little beyond, one very noisy, and one moved off the finest stage's cone by
    amounts about the OFF_MODEL threshold."""
    fsrs_hz, band_hz = (5e12, 500e9, 50e9), 4e12
    device = wm.CascadeInterferometer.table1(fsrs_hz, ports=3, seed=4, spectral="sin")
    low = device.center_hz - band_hz / 2
    sweep_hz = low + band_hz * np.arange(3000) / 2999
    power_w = POWER_W * (1.0 + 0.1 * np.sin(np.arange(3000) / 50.0))
    monitor = power_w if request.param == "offsets fitted" else None
    sweep = device.powers(sweep_hz, POWER_W if monitor is None else power_w, NOISE_W, rng=11)
    dark_w = np.linspace(-2e-6, 3e-6, 9) if request.param == "dark offsets" else np.zeros(9)
    cal = _fitted(
        wm.CascadeCalibrator(fsr_hz=fsrs_hz),
        sweep + dark_w,
        sweep_hz,
        power_monitor_w=monitor,
        dark_w=dark_w if dark_w.any() else None,
    )
    assert all(stage._affine() for stage in cal.stages_) == (monitor is not None)
    rng = np.random.default_rng(5)
    truth = low - 0.01 * band_hz + 1.02 * band_hz * rng.random(80)
    rows = device.powers(truth, POWER_W, NOISE_W, rng=rng)
    noisy = device.powers(truth[:1], POWER_W, 40 * NOISE_W, rng=rng)
    moved = np.array([1.004, 1.008, 1.012, 1.016, 1.024, 1.032, 1.05, 1.2])
    off_cone = rows[1] * np.ones((moved.size, 9))
    off_cone[:, 7] *= moved
    return cal, np.vstack([rows, noisy, off_cone]) + dark_w


@pytest.mark.slow
def test_a_cascade_streams_what_read_gives(cascade):
    cal, rows = cascade
    records = list(cal.stream(rows))
    chain = cal.read(rows)
    for name, expected in (
        ("frequency_hz", chain.frequency_hz[-1]),
        ("frequency_std_hz", chain.std_hz[-1]),
        ("order_error_probability", chain.order_error_probability),
    ):
        found = [getattr(record, name) for record in records]
        np.testing.assert_allclose(found, expected, rtol=RTOL, atol=1e-300, err_msg=name)
    flags = np.array([record.flags for record in records])
    np.testing.assert_array_equal(flags, chain.flags)
    np.testing.assert_array_equal(flags, cal.flags(rows))
    expected = FLAG.OFF_MODEL | FLAG.OUTSIDE_SPAN
    assert all_bits(flags) & expected == expected
    moved = flags[-8:] & FLAG.OFF_MODEL
    assert 0 < np.count_nonzero(moved) < moved.size  # the threshold lies among them


@pytest.mark.slow
def test_each_stage_reads_one_reading_as_the_batch_does(cascade):
    cal, rows = cascade
    chain = cal.read(rows)
    readings = cal._corrected(rows)
    readers = [
        StageReader(stage, error, median)
        for stage, error, median in zip(
            cal.stages_, cal.model_error_hz_, cal.cone_distance_median_, strict=True
        )
    ]
    for k, reading in enumerate(readings):
        coarse = cal.center_hz_
        for index, (reader, block) in enumerate(zip(readers, cal.stage_ports_, strict=True)):
            frequency, std, phase, map_w, distance = reader.read(reading[list(block)], coarse)
            assert frequency == pytest.approx(chain.frequency_hz[index, k], rel=RTOL)
            assert std == pytest.approx(chain.std_hz[index, k], rel=RTOL)
            assert phase == pytest.approx(chain.phase_rad[index, k], rel=RTOL, abs=1e-15)
            np.testing.assert_allclose(map_w, chain.maps[index][k], rtol=RTOL)
            # a distance not worked out is one its bound shows below the threshold
            if np.isnan(distance):
                assert chain.cone_distance[index, k] < reader.on_model
            else:
                assert distance == pytest.approx(chain.cone_distance[index, k], rel=RTOL)
            coarse = frequency


@pytest.mark.slow
def test_a_maximum_likelihood_cascade_streams_through_read(cascade, monkeypatch):
    cal, rows = cascade
    monkeypatch.setattr(cal, "retrieval", "ml")
    read_calls = []
    read = cal.read
    monkeypatch.setattr(cal, "read", lambda powers: read_calls.append(1) or read(powers))
    records = list(cal.stream(rows[:3]))
    assert len(read_calls) == 3
    np.testing.assert_allclose([r.frequency_hz for r in records], read(rows[:3]).frequency_hz[-1])


def test_fewer_readings_than_the_noise_test_can_judge_are_never_scaled():
    """The binomial test of noise_scale cannot reach NOISE_P_VALUE below MIN_SCALED_READINGS
    readings even when every one lies above the median: the shortcut changes nothing."""
    assert 0.5 ** (MIN_SCALED_READINGS - 1) >= NOISE_P_VALUE > 0.5**MIN_SCALED_READINGS
    far = np.full(MIN_SCALED_READINGS - 1, 50.0)
    assert noise_scale(far, 1.0, 0.5) == 1.0
    assert noise_scale(np.append(far, 50.0), 1.0, 0.5) > 1.0


# ---------------------------------------------------------------------------- lines
def test_plain_lines_are_converted_as_files_are_and_others_as_before(device, monkeypatch, tmp_path):
    """Mixed power units, dBm among them: a valid line is converted without convert_rows,
    to the powers read_table gives for the same text; a line with a power-meter code, a dBm
    value out of range, an empty cell or no light goes through convert_rows, which names
    what is wrong (the warning), as it did for every line."""
    sweep_hz = device.sweep_hz(300)
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng=1)
    cal = _fitted(wm.Calibrator(fsr_hz=50e9), sweep, sweep_hz)
    rng = np.random.default_rng(9)
    powers = device.powers(sweep_hz[rng.integers(0, 300, 12)], POWER_W, NOISE_W, rng=rng)
    dbm = 10.0 * np.log10(powers[:, 0] * 1e3)
    good = [
        ",".join(repr(float(v)) for v in row)
        for row in zip(dbm, *(powers[:, 1:] * [1e3, 1e6]).T, strict=True)
    ]
    bad = {
        "-210,0.3,300": "'no reading' code",
        "75,0.3,300": "above 60 dBm",
        "-3,9.91e37,300": "'no reading' code",
        "-3,,300": "NaN, empty or inf",
        "-30,0,-2": "sum to <= 0",
    }
    text = "\n".join(["P1_dBm,P2_mW,P3_uW", *good[:5], *bad, *good[5:]]) + "\n"
    converted = []
    monkeypatch.setattr(stream, "convert_rows", lambda *a: converted.append(1) or convert_rows(*a))
    out = io.StringIO()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = stream_lines(cal, text.splitlines(True), out)
    assert len(converted) == summary.invalid_rows == len(bad)
    reasons = [str(w.message) for w in caught if isinstance(w.message, wm.CalibrationWarning)]
    assert len(reasons) == len(bad)
    for reason, words in zip(reasons, bad.values(), strict=True):
        assert words in reason
    rows = out.getvalue().splitlines()[1:]
    values = np.array([[float(cell) for cell in row.split(",")] for row in rows])
    valid = (values[:, -1].astype(int) & FLAG.INVALID) == 0
    np.testing.assert_array_equal(valid, np.r_[[True] * 5, [False] * 5, [True] * 7])
    (tmp_path / "same.csv").write_text(text)
    powers_w = read_table(tmp_path / "same.csv", need_x=False, allow_invalid=True).powers_w
    np.testing.assert_array_equal(np.isfinite(values[:, 0]), valid)
    np.testing.assert_allclose(values[valid, 0], cal.predict(powers_w[valid]), rtol=RTOL, atol=0)
    np.testing.assert_allclose(
        values[valid, 2], cal.frequency_std_hz(powers_w[valid]), rtol=RTOL, atol=0
    )
