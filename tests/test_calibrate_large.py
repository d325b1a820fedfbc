"""Large sweeps (issue 13): the learned fit on moments, its checks on every k-th reading,
sweeps read in chunks (``Calibrator.fit_chunks``, ``wavemeter calibrate``).

The sampling threshold is lowered per calibrator (``diagnostic_samples``) so that sweeps of
a few thousand readings take the path of sweeps of millions. Tolerances: a fit on the
moments computes the cost, the noise and (through them) the covariance from sums that
cancel, to a few ``2^-53 sum |p|^2`` (``~1e-9`` relative at Table 1's fringes 2000x the
noise: ``RTOL_SUMS``); the delay and the map need no cancellation (``RTOL_FIT``). A
statistic of the sample differs from the whole sweep's by its sampling error, a few
``1 / sqrt(n)``.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.methods import learned_chunks
from wavemeter.calibration.models.learned_fit import gram_objects as _gram_objects
from wavemeter.calibration.models.linear_map import object_delay_derivative, object_vectors
from wavemeter.calibration.models.moments import FringeMoments
from wavemeter.calibration.models.subsample import SweepSample, diagnostic_stride, median_step_hz
from wavemeter.io import read_table, write_table
from wavemeter.jobs import calibrate as calibrate_job
from wavemeter.model.uncertainty import fit_parameter_covariance
from wavemeter.simulation.drift import slow_power_drift

from .helpers import NOISE_W, POWER_W, darken, run_cli

FSR_HZ = 50e9
SAMPLES = 20_000
#: readings diagnosed on the sampled path in these tests (stride 16 for SAMPLES)
LIMIT = 2048
#: quantities from cancelling sums (cost, noise, covariance): a few 2^-53 sum|p|^2 / J
RTOL_SUMS = 1e-8
#: delay and map: no cancellation (normal equations of a well-conditioned fit)
RTOL_FIT = 1e-11


def sweep(samples=SAMPLES, seed=7, ports=3, span_fsr=4.0, power_w=POWER_W):
    device = wm.Interferometer.table1(ports, seed=seed)
    frequency = device.sweep_hz(samples, span_fsr)
    return frequency, device.powers(frequency, power_w, NOISE_W, rng=seed + 1)


def calibrator(limit: int | None = LIMIT, fsr_hz: float = FSR_HZ) -> wm.Calibrator:
    """A calibrator that diagnoses at most ``limit`` readings (None: every one)."""
    cal = wm.Calibrator(fsr_hz)
    cal.diagnostic_samples = 10**12 if limit is None else limit
    return cal


def quiet_fit(cal, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        return cal.fit(*args, **kwargs)


def chunked(frequency, powers, monitor=None, seed=0):
    """The sweep in chunks of random sizes, empty and single readings among them."""
    rng = np.random.default_rng(seed)
    edges = [0]
    while edges[-1] < frequency.size:
        edges.append(edges[-1] + int(rng.choice([0, 1, 7, 333, 4096])))
    edges[-1] = frequency.size
    for low, high in zip(edges[:-1], edges[1:], strict=True):
        yield frequency[low:high], powers[low:high], None if monitor is None else monitor[low:high]


def relative(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def correlation_and_scale(covariance):
    scale = np.sqrt(np.diag(covariance))
    return covariance / np.outer(scale, scale), scale


# ---------------------------------------------------------------------------- the sample
@pytest.mark.parametrize(
    ("samples", "stride"), [(1, 1), (2048, 1), (2049, 2), (4096, 2), (4097, 4), (20_000, 16)]
)
def test_stride_is_the_smallest_power_of_two_that_keeps_the_limit(samples, stride):
    assert diagnostic_stride(samples, LIMIT) == stride


def test_the_sample_is_every_kth_reading_however_the_sweep_is_chunked():
    frequency, powers = sweep()
    monitor = POWER_W * slow_power_drift(SAMPLES, 0.3, rng=3)
    stride = diagnostic_stride(SAMPLES, LIMIT)
    for seed in range(3):
        sample = SweepSample(LIMIT)
        for chunk in chunked(frequency, powers, monitor, seed):
            sample.add(*chunk)
        assert sample.stride == stride and sample.samples == SAMPLES
        assert np.array_equal(sample.frequency_hz, frequency[::stride])
        assert np.array_equal(sample.powers_w, powers[::stride])
        assert np.array_equal(sample.monitor_w, monitor[::stride])
        assert (sample.low_hz, sample.high_hz) == (frequency.min(), frequency.max())
        total = powers.sum(axis=1)
        assert sample.total_range_w == pytest.approx((total.min(), total.max()), rel=1e-15)
        assert sample.largest_w == np.abs(powers).max()
        assert sample.monitor_mean_w == pytest.approx(monitor.mean(), rel=1e-14)
        expected_std = monitor.std() / monitor.mean()
        assert sample.monitor_relative_std == pytest.approx(expected_std, rel=1e-12)


def sorted_median_step(frequency) -> float:
    """The definition: median of the steps between the sorted distinct frequencies."""
    steps = np.diff(np.sort(frequency))
    return float(np.median(steps[steps > 0]))


LINE = 193.3e12 + 10e6 * np.arange(5000.0)
SWEEPS = {
    "rising": LINE,
    "falling": LINE[::-1],
    "repeated readings": np.repeat(LINE, 3),
    "uneven": 193.3e12 + np.cumsum(np.random.default_rng(1).uniform(5e6, 15e6, 5000)),
    "random order": np.random.default_rng(2).permutation(LINE),
}


@pytest.mark.parametrize("name", SWEEPS)
def test_median_step_is_unchanged_without_the_sort(name):
    frequency = SWEEPS[name]
    assert median_step_hz(frequency) == sorted_median_step(frequency)


@pytest.mark.parametrize(
    ("name", "rtol"),
    [
        ("rising", 1e-3),  # evenly spaced: exact to k / N
        ("falling", 1e-3),
        ("repeated readings", 1e-3),
        # steps uniform in 5..15 MHz: means of 4 against the median of 5000, each known to
        # ~0.6 %
        ("uneven", 0.03),
        # one reading in 4 of random frequencies: the sample's median step scaled; the
        # median of ~1250 exponential spacings has a relative error 1 / (ln 2 sqrt(n)),
        # 4 %: 4 of them
        ("uniform random", 0.16),
    ],
)
def test_the_sample_estimates_the_median_step(name, rtol):
    if name == "uniform random":
        frequency = np.random.default_rng(3).uniform(193.3e12, 193.35e12, 5000)
    else:
        frequency = SWEEPS[name]
    sample = SweepSample(1250)
    for chunk in chunked(frequency, np.ones((frequency.size, 3))):
        sample.add(*chunk)
    assert sample.stride > 1
    assert sample.median_step_hz() == pytest.approx(sorted_median_step(frequency), rel=rtol)


# ---------------------------------------------------------------------------- moments
@pytest.mark.parametrize("affine", [False, True])
def test_moments_give_the_residual_and_the_products_of_the_objects(affine):
    frequency, powers = sweep(4000)
    monitor = 2.0 * slow_power_drift(4000, 0.3, rng=4)  # any unit
    center = float(frequency.mean())
    moments = FringeMoments(2.0 / FSR_HZ, center).add(frequency, powers, monitor)
    delay = 1.0 / 51.5e9
    objects = object_vectors(frequency, center, delay, monitor, affine)
    derivative = object_delay_derivative(frequency, center, delay, monitor, affine)
    xx, dx, dd = moments.object_gram(delay, affine)
    for got, want in ((xx, objects.T @ objects), (dx, derivative.T @ objects)):
        assert relative(got, want) < 1e-12
    assert relative(dd, derivative.T @ derivative) < 1e-12
    map_ = moments.map_at(delay, affine)
    residual = powers - objects @ map_.T
    direct = np.einsum("ij,ij->j", residual, residual)
    assert moments.port_residual_w2(delay, map_) == pytest.approx(direct, rel=RTOL_SUMS)


@pytest.mark.parametrize("affine", [False, True])
def test_rows_with_the_sweeps_products_give_its_covariance(affine):
    frequency, powers = sweep(4000)
    monitor = 3.0 * slow_power_drift(4000, 0.3, rng=5)
    center = float(frequency.mean())
    moments = FringeMoments(2.0 / FSR_HZ, center).add(frequency, powers, monitor)
    delay = 1.0 / 51.5e9
    scale = monitor / monitor.mean()
    map_ = moments.map_at(delay, affine)
    map_[:, :3] *= moments.mean_scale
    noise = np.array([5e-7, 6e-7, 4e-7])
    direct = fit_parameter_covariance(
        object_vectors(frequency, center, delay, scale, affine),
        object_delay_derivative(frequency, center, delay, scale, affine),
        map_,
        noise,
        weighted=False,
    )
    objects, derivative = _gram_objects(moments, delay, affine, moments.mean_scale)
    assert objects.shape == derivative.shape == (2 * map_.shape[1], map_.shape[1])
    stand_in = fit_parameter_covariance(objects, derivative, map_, noise, weighted=False)
    (want_c, want_s), (got_c, got_s) = map(correlation_and_scale, (direct, stand_in))
    assert np.abs(got_c - want_c).max() < 1e-9
    assert got_s == pytest.approx(want_s, rel=1e-9)


# ---------------------------------------------------------------------------- the fit
def compare_fits(sampled, full, misfit: bool = False):
    """The sampled fit describes the fit on every reading. With a misfit found, the noise is
    the model-free estimate of the readings diagnosed: the sample's, on its own degrees of
    freedom, within a few of its standard errors of the whole sweep's."""
    assert sampled.n_samples_ == full.n_samples_ and sampled.span_hz_ == full.span_hz_
    assert sampled.delay_s_ == pytest.approx(full.delay_s_, rel=RTOL_FIT)
    assert relative(sampled.map_, full.map_) < 1e-9
    assert np.abs(sampled.offset_w_ - full.offset_w_).max() <= 1e-9 * np.abs(full.map_).max()
    n = sampled.diagnostics_["diagnostic_samples"]
    if misfit:
        assert sampled.noise_dof_ == pytest.approx(full.noise_dof_ * n / full.n_samples_, rel=0.01)
        noise_rtol = 5 / np.sqrt(2 * sampled.noise_dof_)
    else:
        assert sampled.noise_dof_ == full.noise_dof_
        noise_rtol = RTOL_SUMS
    for name in ("cost_", "noise_std_w_", "delay_std_s_"):
        assert getattr(sampled, name) == pytest.approx(getattr(full, name), rel=RTOL_SUMS)
    assert sampled.port_noise_std_w_ == pytest.approx(full.port_noise_std_w_, rel=noise_rtol)
    (want_c, want_s), (got_c, got_s) = map(
        correlation_and_scale, (full.parameter_covariance_, sampled.parameter_covariance_)
    )
    assert np.abs(got_c - want_c).max() < (0.01 if misfit else 1e-7)
    assert got_s == pytest.approx(want_s, rel=noise_rtol)
    # the RMS error on the sample: sampling error 1 / sqrt(2 n) of a noise-driven RMS
    assert sampled.calibration_rms_hz_ == pytest.approx(
        full.calibration_rms_hz_, rel=5 / np.sqrt(2 * n)
    )
    assert sampled.total_power_range_w_ == pytest.approx(full.total_power_range_w_, rel=1e-12)


def test_a_long_sweep_is_fitted_on_moments_and_diagnosed_on_a_sample():
    frequency, powers = sweep()
    sampled = quiet_fit(calibrator(), powers, frequency)
    full = quiet_fit(calibrator(None), powers, frequency)
    assert sampled.diagnostics_["diagnostic_samples"] == -(-SAMPLES // 16)
    assert full.diagnostics_["diagnostic_samples"] == SAMPLES
    compare_fits(sampled, full)
    assert sampled.diagnostics_["warnings"] == full.diagnostics_["warnings"] == []
    assert sampled.diagnostics_["fsr_estimate_hz"] == pytest.approx(
        full.diagnostics_["fsr_estimate_hz"], rel=1e-4
    )


def test_a_monitored_sweep_with_offsets_is_the_full_fit():
    frequency, _ = sweep()
    power = POWER_W * slow_power_drift(SAMPLES, 0.3, rng=18)
    dark = np.array([3e-6, -2e-6, 1e-6])
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=7), dark_offset_w=dark)
    powers = device.powers(frequency, power, NOISE_W, rng=8)
    monitor = 1e3 * power  # mW: any unit
    sampled = quiet_fit(calibrator(), powers, frequency, monitor)
    full = quiet_fit(calibrator(None), powers, frequency, monitor)
    assert np.any(full.offset_w_ != 0)  # offsets fitted: a detector_offset warning
    compare_fits(sampled, full, misfit=True)
    assert [note["cause"] for note in sampled.diagnostics_["warnings"]] == [
        note["cause"] for note in full.diagnostics_["warnings"]
    ]


def test_dark_readings_are_subtracted_on_the_sampled_path():
    frequency, powers = sweep()
    dark = np.array([1e-6, 2e-6, -1e-6])
    sampled = quiet_fit(calibrator(), powers + dark, frequency, dark_w=dark)
    full = quiet_fit(calibrator(None), powers + dark, frequency, dark_w=dark)
    compare_fits(sampled, full)
    assert np.array_equal(sampled.dark_w_, dark)


@pytest.mark.parametrize(
    ("fault", "cause"),
    [("power drift", "power_drift"), ("dead port", "dead_port")],
)
def test_the_sample_finds_what_the_whole_sweep_shows(fault, cause):
    frequency, powers = sweep(ports=4, seed=6, span_fsr=3.0)
    if fault == "power drift":
        drift = slow_power_drift(SAMPLES, 0.02, rng=6)
        powers = sweep(ports=4, seed=6, span_fsr=3.0, power_w=POWER_W * drift)[1]
    else:
        powers = darken(powers, [1])
    with pytest.warns(wm.CalibrationWarning) as record:
        sampled = calibrator().fit(powers, frequency)
    assert cause in [note.message.cause for note in record]
    assert cause in [note["cause"] for note in sampled.diagnostics_["warnings"]]


def test_the_summary_says_how_many_readings_were_diagnosed(tmp_path):
    frequency, powers = sweep()
    sampled = quiet_fit(calibrator(), powers, frequency)
    text = sampled.summary().text
    assert f"{frequency.size} (checks and diagnostics on 1250, every k-th reading)" in text
    assert "checks and diagnostics on" not in (
        quiet_fit(calibrator(None), powers, frequency).summary().text
    )
    sampled.save(tmp_path / "cal.json")
    loaded = wm.load_calibration(tmp_path / "cal.json")
    assert loaded.diagnostics_["diagnostic_samples"] == 1250
    assert np.array_equal(loaded.parameter_covariance_, sampled.parameter_covariance_)


# ---------------------------------------------------------------------------- in chunks
def fitted_state(cal) -> dict:
    state = {name: value for name, value in vars(cal).items() if name.endswith("_")}
    state.pop("delay_search_", None)  # not saved
    return state


def assert_same(a, b):
    assert a.keys() == b.keys()
    for name in a:
        assert json.dumps(a[name], default=np.ndarray.tolist) == json.dumps(
            b[name], default=np.ndarray.tolist
        ), name


def test_a_short_sweep_in_chunks_is_the_fit_bit_for_bit():
    frequency, powers = sweep(3000)
    dark = np.array([1e-7, 0.0, -1e-7])
    monitor = POWER_W * slow_power_drift(3000, 0.3, rng=2)
    whole = quiet_fit(
        wm.Calibrator(FSR_HZ), powers, frequency, monitor, ["a", "b", "c"], dark_w=dark
    )
    in_chunks = wm.Calibrator(FSR_HZ)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        in_chunks.fit_chunks(chunked(frequency, powers, monitor), ["a", "b", "c"], dark_w=dark)
    assert_same(fitted_state(in_chunks), fitted_state(whole))


def test_a_long_sweep_in_chunks_is_the_fit_to_rounding():
    frequency, powers = sweep()
    whole = quiet_fit(calibrator(), powers, frequency)
    in_chunks = calibrator()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        in_chunks.fit_chunks(chunked(frequency, powers, seed=5))
    assert in_chunks.delay_s_ == pytest.approx(whole.delay_s_, rel=1e-14)
    assert relative(in_chunks.map_, whole.map_) < 1e-12
    assert in_chunks.noise_std_w_ == pytest.approx(whole.noise_std_w_, rel=RTOL_SUMS)
    assert relative(in_chunks.parameter_covariance_, whole.parameter_covariance_) < 1e-7
    # the same sample, the same diagnostics to the rounding of the map
    assert in_chunks.calibration_rms_hz_ == pytest.approx(whole.calibration_rms_hz_, rel=1e-9)
    fit_a, fit_b = in_chunks.diagnostics_["fit"], whole.diagnostics_["fit"]
    assert fit_a["residual_rms_w"] == pytest.approx(fit_b["residual_rms_w"], rel=1e-9)
    assert in_chunks.diagnostics_["ports"] == whole.diagnostics_["ports"]


def test_a_wrong_design_fsr_is_refused_before_the_moments_grow(monkeypatch):
    frequency, powers = sweep()
    monkeypatch.setattr(learned_chunks, "MAX_MOMENT_BYTES", 1 << 20)
    # 50 Hz: a bin per reading, 0.5 kB each: the moments are dropped at 1 MiB
    moments, sample = calibrator(fsr_hz=50.0)._accumulate(chunked(frequency, powers))
    assert moments is None and sample.samples == SAMPLES
    with pytest.raises(wm.InputError, match="not resolved by the sweep") as info:
        calibrator(fsr_hz=50.0).fit_chunks(chunked(frequency, powers))
    assert info.value.parameter == "fsr_hz"


def test_a_sweep_over_too_many_fringes_for_the_moments_is_refused(monkeypatch):
    frequency, powers = sweep()
    monkeypatch.setattr(learned_chunks, "MAX_MOMENT_BYTES", 1000)
    with pytest.raises(wm.InputError, match="binned moments would take more than") as info:
        calibrator().fit(powers, frequency)
    assert info.value.parameter == "fsr_hz"


def test_chunks_are_checked_and_named():
    frequency, powers = sweep(3000)
    bad = powers.copy()
    bad[1500, 1] = np.nan
    chunks = [(frequency[:1000], bad[:1000], None), (frequency[1000:], bad[1000:], None)]
    with pytest.raises(wm.InputError, match=r"chunk 1 \(readings from 1000 on.*NaN"):
        wm.Calibrator(FSR_HZ).fit_chunks(chunks)
    mixed = [(frequency[:10], powers[:10], np.ones(10)), (frequency[10:], powers[10:], None)]
    with pytest.raises(wm.InputError, match="chunk 1.*always or never a monitor"):
        wm.Calibrator(FSR_HZ).fit_chunks(mixed)
    with pytest.raises(wm.InputError, match="chunk 0 must be"):
        wm.Calibrator(FSR_HZ).fit_chunks([powers])
    with pytest.raises(wm.InputError, match="need at least 4 samples"):
        wm.Calibrator(FSR_HZ).fit_chunks([(frequency[:3], powers[:3], None)])
    with pytest.raises(wm.InputError, match="dark_w must be 3"):
        wm.Calibrator(FSR_HZ).fit_chunks(chunked(frequency, powers), dark_w=[0.0, 0.0])


def test_a_thermal_calibrator_fits_every_reading_at_once():
    frequency, powers = sweep(3000)
    with pytest.raises(wm.InputError, match="give the whole sweep to fit"):
        wm.ThermalCalibrator(FSR_HZ).fit_chunks(chunked(frequency, powers))


# ---------------------------------------------------------------------------- the command
def write_sweep(path, frequency, powers, rows_invalid=()):
    powers = powers.copy()
    powers[list(rows_invalid), 0] = np.nan
    columns = {"frequency_hz": frequency, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    write_table(path, columns)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_calibrate_reads_in_chunks_and_gives_the_fit(tmp_path, capsys, monkeypatch, suffix):
    pytest.importorskip("pyarrow")
    frequency, powers = sweep()
    path, out = tmp_path / f"sweep{suffix}", tmp_path / "cal.json"
    write_sweep(path, frequency, powers, rows_invalid=[7])
    monkeypatch.setattr(wm.Calibrator, "diagnostic_samples", LIMIT)
    monkeypatch.setattr(calibrate_job, "CHUNK_ROWS", 3000)  # several chunks
    code, _, err = run_cli(capsys, f"calibrate {path} -o {out} --drop-invalid --fsr 50GHz")
    assert code == 0, err
    assert "skipped 1 invalid row(s), first: " in err
    table = read_table(path, need_x=True, allow_invalid=True).valid_only()
    expected = quiet_fit(wm.Calibrator(FSR_HZ), table.powers_w, table.x_hz)
    saved = json.loads(out.read_text())
    loaded = wm.load_calibration(out)
    assert loaded.delay_s_ == pytest.approx(expected.delay_s_, rel=1e-14)
    assert relative(loaded.map_, expected.map_) < 1e-12
    assert loaded.diagnostics_["diagnostic_samples"] == expected.diagnostics_["diagnostic_samples"]
    assert saved["metadata"]["rows"] == SAMPLES - 1 and saved["metadata"]["dropped_rows"] == 1
    assert saved["metadata"]["port_columns"] == ["p1_w", "p2_w", "p3_w"]


def test_calibrate_in_chunks_of_a_short_sweep_is_the_whole_read_fit(tmp_path, capsys):
    frequency, powers = sweep(3000)
    path, out = tmp_path / "sweep.csv", tmp_path / "cal.json"
    write_sweep(path, frequency, powers)
    assert run_cli(capsys, f"calibrate {path} -o {out} --quiet")[0] == 0
    table = read_table(path, need_x=True)
    expected = quiet_fit(
        wm.Calibrator(FSR_HZ), table.powers_w, table.x_hz, None, ["p1_w", "p2_w", "p3_w"]
    )
    assert_same(
        fitted_state(wm.load_calibration(out)),
        fitted_state(wm.load_calibration(_saved(expected, tmp_path))),
    )


def _saved(calibration, folder):
    path = folder / "expected.json"
    calibration.save(path)
    return path


# ---------------------------------------------------------------------------- benchmark
@pytest.fixture(scope="module")
def scale():
    import importlib

    from .helpers import BENCHMARKS

    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("scale")


@pytest.mark.slow
def test_benchmark_times_the_whole_fit_both_ways(scale, monkeypatch):
    monkeypatch.setattr(wm.Calibrator, "diagnostic_samples", LIMIT)
    row = scale.whole_fit_row(5_000, runs=1)
    assert len(row) == len(scale.WHOLE_FIT_HEADERS)
    assert float(row[1]) > 0 and float(row[2]) > 0
    assert row[3] == str(-(-5_000 // 4))  # every 4th reading diagnosed


@pytest.mark.slow
def test_benchmark_calibrates_files_of_both_formats(scale):
    pytest.importorskip("pyarrow")
    from .helpers import table_rows

    text = scale.calibrate_table((2_000, 4_000))
    tables = [table_rows(part) for part in text.split("\n\n")]
    assert [row[0] for row in tables[0][2:]] == ["CSV", "CSV", "Parquet", "Parquet"]
    assert all(float(row[5]) > 0 for row in tables[0][2:])  # peak RSS (MiB)
    assert [row[-1] in ("PASS", "FAIL") for row in tables[1][2:]] == [True, True]
