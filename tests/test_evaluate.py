"""Evaluation against the true frequency: whole-FSR errors counted, modulo-FSR labelled.

The scenario of issue 15: a Table 1 device (seed 7) calibrated on one FSR and tested on
five reads 80 % of the readings whole FSRs off; a calibration whose FSR is an alias of the
device's (4.13 MHz instead of 51.5 GHz) reads every reading wrong. The expected figures
come from the test frequencies and the true device (its Cramer-Rao bound), not from the
code under test; tolerances are the sampling spread of an RMS over the test readings.
"""

from __future__ import annotations

import json
import shlex

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.analysis import crlb_per_reading_hz, evaluate_calibrations
from wavemeter.cli import main
from wavemeter.exceptions import InputError
from wavemeter.model.cone import delay_phase_rad

POWER_W = 1e-3
NOISE_W = 5e-7
SWEEP_SAMPLES = 2001
TEST_SAMPLES = 5000
#: the aliased FSR the issue's `calibrate --fsr 5e6` fitted
ALIAS_FSR_HZ = 4.13e6
#: test readings kept this far from the branch cuts centre +- (k + 1/2) FSR (about 70 CRLB),
#: so that which alias each one is read at is certain
CUT_MARGIN_HZ = 1e9
#: standard deviations of sampling spread allowed
SIGMAS = 4


@pytest.fixture(scope="module")
def device() -> wm.Interferometer:
    return wm.Interferometer.table1(ports=3, seed=7)


@pytest.fixture(scope="module")
def sweep_hz(device) -> np.ndarray:
    return device.sweep_hz(SWEEP_SAMPLES, span_fsr=1)


@pytest.fixture(scope="module")
def calibration(device, sweep_hz) -> wm.Calibrator:
    powers = device.powers(sweep_hz, POWER_W, NOISE_W, rng=1)
    return wm.Calibrator(fsr_hz=50e9, fsr_tolerance=0.2).fit(powers, sweep_hz)


def true_crlb_hz(device, frequency_hz) -> np.ndarray:
    """Per-reading Cramer-Rao bound (Hz) of the true device at the true frequency."""
    phase = delay_phase_rad(frequency_hz, device.center_hz, device.delay_s)
    return wm.crlb_frequency_std(device.true_map(), phase, POWER_W, NOISE_W, device.true_fsr_hz)


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def rms_spread(bound_hz) -> float:
    """Relative standard deviation of the RMS of zero-mean Gaussian errors of std ``bound_hz``
    (half that of their mean square: sqrt(2 sum s^4) / sum s^2)."""
    return 0.5 * np.sqrt(2 * np.sum(bound_hz**4)) / np.sum(bound_hz**2)


def alias_order(frequency_hz, center_hz, fsr_hz) -> np.ndarray:
    """Which FSR about ``center_hz`` each frequency lies in (0: the calibrated one)."""
    return np.round((np.asarray(frequency_hz) - center_hz) / fsr_hz)


@pytest.fixture(scope="module")
def five_fsr_test(device, sweep_hz):
    """Test readings uniform over five true FSRs about the sweep centre, off the cuts."""
    centre, fsr = 0.5 * (sweep_hz[0] + sweep_hz[-1]), device.true_fsr_hz
    frequency = np.random.default_rng(3).uniform(centre - 2.5 * fsr, centre + 2.5 * fsr, 5000)
    offset = frequency - centre - alias_order(frequency, centre, fsr) * fsr
    frequency = frequency[np.abs(offset) < 0.5 * fsr - CUT_MARGIN_HZ]
    return frequency, device.powers(frequency, POWER_W, NOISE_W, rng=2)


@pytest.fixture(scope="module")
def one_fsr_test(device, sweep_hz):
    """Test readings uniform over the middle 90 % of the calibrated FSR."""
    centre, fsr = 0.5 * (sweep_hz[0] + sweep_hz[-1]), device.true_fsr_hz
    frequency = np.random.default_rng(4).uniform(centre - 0.45 * fsr, centre + 0.45 * fsr, 5000)
    return frequency, device.powers(frequency, POWER_W, NOISE_W, rng=4)


def aliased_file(calibration, folder) -> str:
    """The calibration saved with its FSR replaced by the 4.13 MHz alias (what an unguarded
    fit with a design FSR of 5 MHz returned): the same map, phases read on a tiny FSR."""
    path = folder / "aliased.wmcal.json"
    calibration.save(path)
    document = json.loads(path.read_text())
    document["fsr_hz"] = ALIAS_FSR_HZ
    document["state"]["delay_s"] = 1 / ALIAS_FSR_HZ
    path.write_text(json.dumps(document))
    return str(path)


# ---------------------------------------------------------------------------- library
def test_one_fsr_calibration_on_five_fsrs_counts_the_whole_fsr_errors(
    device, sweep_hz, calibration, five_fsr_test
):
    frequency, powers = five_fsr_test
    report = evaluate_calibrations({"learned": calibration}, powers, frequency)
    figures = report["methods"]["learned"]
    centre, fsr = 0.5 * (sweep_hz[0] + sweep_hz[-1]), device.true_fsr_hz
    order = alias_order(frequency, centre, fsr)
    outside = np.mean((frequency < sweep_hz[0]) | (frequency > sweep_hz[-1]))
    assert figures["outside_span_fraction"] == outside
    assert outside == pytest.approx(0.8, abs=SIGMAS * np.sqrt(0.8 * 0.2 / frequency.size))
    # off the cuts, a reading is read k FSRs off exactly when it lies k FSRs out
    assert figures["gross_error_fraction"] == np.mean(order != 0)
    # the error is -k FSR plus a CRLB-size rest: the RMS norm moves by at most that rest
    bound = true_crlb_hz(device, frequency)
    whole_fsrs = rms(order * fsr)
    assert whole_fsrs > 70e9  # sqrt(2) FSR, the "70 GHz RMS"
    assert abs(figures["rms_abs_hz"] - whole_fsrs) < 2 * rms(bound)
    # modulo the FSR: the CRLB with the 3/N of the fit, plus the fitted FSR's error carried
    # k FSRs out (a delay error grows with the distance from the centre)
    fsr_error = (frequency - centre) * (calibration.fsr_hz_ - fsr) / fsr
    expected = np.sqrt(rms(bound) ** 2 * (1 + 3 / SWEEP_SAMPLES) + rms(fsr_error) ** 2)
    assert figures["rms_mod_fsr_hz"] == pytest.approx(expected, rel=SIGMAS * rms_spread(bound))
    # the bound under the calibration's model: noise estimated from N n residuals
    noise_spread = 1 / np.sqrt(2 * (SWEEP_SAMPLES - 3) * 3)
    assert report["crlb_rms_hz"] == pytest.approx(rms(bound), rel=SIGMAS * noise_spread)
    assert report["noise_std_w"] == pytest.approx(NOISE_W, rel=SIGMAS * noise_spread)
    crlb = report["crlb_rms_hz"]
    assert figures["rms_abs_over_crlb"] == figures["rms_abs_hz"] / crlb > 1000
    assert figures["rms_mod_fsr_over_crlb"] == figures["rms_mod_fsr_hz"] / crlb
    assert report["crlb_method"] == "learned" and report["coarse_from"] is None
    assert figures["span_hz"] == [sweep_hz[0], sweep_hz[-1]]
    json.dumps(report)


def test_inside_the_span_absolute_and_modulo_errors_agree_at_the_crlb(
    device, calibration, one_fsr_test
):
    frequency, powers = one_fsr_test
    figures = evaluate_calibrations({"learned": calibration}, powers, frequency)["methods"]
    figures = figures["learned"]
    bound = true_crlb_hz(device, frequency)
    assert figures["rms_abs_hz"] == pytest.approx(figures["rms_mod_fsr_hz"], rel=1e-12)
    assert figures["rms_abs_hz"] == pytest.approx(
        rms(bound) * np.sqrt(1 + 3 / SWEEP_SAMPLES), rel=SIGMAS * rms_spread(bound)
    )
    assert figures["outside_span_fraction"] == figures["gross_error_fraction"] == 0
    assert figures["max_abs_hz"] < 6 * bound.max()  # Gaussian tail over 5000 readings


def test_an_aliased_fsr_reads_every_reading_wrong(calibration, one_fsr_test, tmp_path):
    """The issue's `--fsr 5e6` calibration: modulo its 4.13 MHz FSR any reading is within
    2 MHz (the "1.17 MHz RMS"), in absolute terms it is the test span's spread off."""
    frequency, powers = one_fsr_test
    aliased = wm.load_calibration(aliased_file(calibration, tmp_path))
    report = evaluate_calibrations({"good": calibration, "aliased": aliased}, powers, frequency)
    figures = report["methods"]["aliased"]
    # it returns centre +- FSR'/2: the RMS norm of its error is that of the truth about the
    # centre, give or take FSR'/2
    spread = rms(frequency - calibration.center_hz_)
    assert spread > 10e9
    assert abs(figures["rms_abs_hz"] - spread) <= ALIAS_FSR_HZ / 2
    assert figures["rms_mod_fsr_hz"] <= ALIAS_FSR_HZ / 2
    # every reading farther than FSR' from the centre is off by more than FSR'/2
    far = np.mean(np.abs(frequency - calibration.center_hz_) > ALIAS_FSR_HZ)
    assert figures["gross_error_fraction"] >= far > 0.999
    assert figures["outside_span_fraction"] == 0
    assert figures["fsr_hz"] == ALIAS_FSR_HZ
    # the bound is the first learned calibration's, so the good one is rated against it
    assert report["crlb_method"] == "good"
    assert figures["rms_abs_over_crlb"] > 100 * report["methods"]["good"]["rms_abs_over_crlb"]


@pytest.fixture(scope="module")
def calibration_set(device) -> wm.CalibrationSet:
    frequency = device.sweep_hz(5000, span_fsr=5)
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=5)
    return wm.CalibrationSet(50e9).fit(powers, frequency)


@pytest.mark.slow
def test_a_set_reads_absolute_frequency_and_counts_wrong_coarse_values(
    device, calibration_set, five_fsr_test
):
    frequency, powers = five_fsr_test
    bound = true_crlb_hz(device, frequency)
    window_samples = 1000
    tolerance = SIGMAS * rms_spread(bound)
    report = evaluate_calibrations({"set": calibration_set}, powers, frequency)
    figures = report["methods"]["set"]
    assert report["coarse_from"] == "truth"
    assert figures["rms_abs_hz"] == pytest.approx(figures["rms_mod_fsr_hz"], rel=1e-12)
    assert figures["rms_abs_hz"] == pytest.approx(
        rms(bound) * np.sqrt(1 + 3 / window_samples), rel=tolerance
    )
    assert figures["outside_span_fraction"] == figures["gross_error_fraction"] == 0
    assert figures["span_hz"] == list(calibration_set.covered_hz())

    # a coarse value 0.6 FSR high picks the alias one FSR up: that reading is one FSR off
    fsr = calibration_set.fsr_hz_
    coarse = frequency.copy()
    wrong = (np.arange(frequency.size) % 10 == 0) & (frequency < frequency.max() - fsr)
    coarse[wrong] += 0.6 * fsr
    report = evaluate_calibrations({"set": calibration_set}, powers, frequency, coarse_hz=coarse)
    figures = report["methods"]["set"]
    assert report["coarse_from"] == "coarse_hz"
    assert figures["gross_error_fraction"] == np.mean(wrong)
    # the error is one FSR on the wrong rows plus a CRLB-size rest on all: the RMS norm
    # moves by at most that rest
    assert abs(figures["rms_abs_hz"] - fsr * np.sqrt(np.mean(wrong))) < 2 * rms(bound)
    # modulo the FSR, the wrong rows are read as well as the others (by the next window)
    assert figures["rms_mod_fsr_hz"] == pytest.approx(
        rms(bound) * np.sqrt(1 + 3 / window_samples), rel=tolerance
    )


def test_crlb_per_reading_is_the_true_devices_bound(device, calibration, calibration_set):
    frequency = device.center_hz + np.linspace(-2.4, 2.4, 2001) * device.true_fsr_hz
    powers = device.powers(frequency, POWER_W, NOISE_W, rng=6)
    truth = true_crlb_hz(device, frequency)
    # each reading's bound scales with its source-power estimate: relative std noise / |a_P|
    phase = delay_phase_rad(frequency, device.center_hz, device.delay_s)
    cone = np.stack([np.cos(phase), np.sin(phase), np.full(phase.size, np.sqrt(2))])
    power_spread = NOISE_W / (POWER_W * np.linalg.norm(device.true_map() @ cone, axis=0))
    # noise estimated from N n residuals (a window of the set: a fifth of N)
    for fitted, samples in ((calibration, SWEEP_SAMPLES), (calibration_set, 1000)):
        bound = crlb_per_reading_hz(fitted, powers, frequency)
        assert bound.shape == frequency.shape
        noise_spread = 1 / np.sqrt(2 * (samples - 3) * 3)
        assert np.all(np.abs(bound / truth - 1) < SIGMAS * (noise_spread + power_spread))
    conventional = wm.ConventionalCalibrator(50e9).fit(
        device.powers(device.sweep_hz(201), POWER_W, NOISE_W, rng=7), device.sweep_hz(201)
    )
    assert crlb_per_reading_hz(conventional, powers, frequency) is None
    beyond = frequency[-1:] + device.true_fsr_hz  # 3.4 FSRs out, the set covers 2.5
    assert np.isnan(crlb_per_reading_hz(calibration_set, powers[-1:], beyond)).all()


def test_evaluating_nothing_or_mismatched_truth_is_refused(calibration, one_fsr_test):
    frequency, powers = one_fsr_test
    with pytest.raises(InputError, match="no calibration"):
        evaluate_calibrations({}, powers, frequency)
    with pytest.raises(InputError):
        evaluate_calibrations({"learned": calibration}, powers, frequency[:-1])


# ---------------------------------------------------------------------------- command line
def run(capsys, command: str) -> tuple[str, str]:
    """Run ``wavemeter COMMAND`` that must succeed: stdout, stderr."""
    code = main(shlex.split(command))
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return captured.out, captured.err


@pytest.fixture(scope="module")
def cli_files(tmp_path_factory) -> dict:
    """The issue's files: a one-FSR sweep and its calibration, a five-FSR sweep with a test
    file and its per-FSR set, of the same seed-7 device."""
    folder = tmp_path_factory.mktemp("evaluate")
    files = {
        "sweep": folder / "sweep.csv",
        "cal": folder / "chip.wmcal.json",
        "wide": folder / "wide.csv",
        "test": folder / "wide-test.csv",
        "set": folder / "set.wmcal.json",
    }
    for command in (
        f"simulate -o {files['sweep']} --seed 7 --test 2000",
        f"simulate -o {files['wide']} --seed 7 --span-fsr 5 --samples 5000 --test 5000",
        f"calibrate {files['sweep']} -o {files['cal']}",
        f"calibrate {files['wide']} -o {files['set']} --per-fsr",
    ):
        assert main(shlex.split(command + " --quiet")) == 0
    return files


@pytest.mark.slow
def test_cli_shows_the_absolute_error_first_and_warns_of_readings_outside_the_span(
    device, cli_files, capsys
):
    calibration = wm.load_calibration(cli_files["cal"])
    test = np.loadtxt(cli_files["test"], delimiter=",", skiprows=1)
    frequency = test[:, 0]
    low, high = calibration.span_hz_
    outside = np.mean((frequency < low) | (frequency > high))
    command = f"evaluate {cli_files['cal']} {cli_files['test']}"
    report = json.loads(run(capsys, command + " --json")[0])
    figures = report["methods"]["learned"]
    assert figures["outside_span_fraction"] == outside == pytest.approx(0.8, abs=0.03)
    # readings near a branch cut may be read one FSR either way
    fsr = calibration.fsr_hz_
    order = alias_order(frequency, calibration.center_hz_, fsr)
    offset = frequency - calibration.center_hz_ - order * fsr
    near_cut = np.mean(np.abs(np.abs(offset) - 0.5 * fsr) < 0.1e9)
    assert abs(figures["gross_error_fraction"] - outside) <= near_cut
    bound = rms(true_crlb_hz(device, frequency))
    assert abs(figures["rms_abs_hz"] - rms(order * fsr)) < 2 * bound + fsr * np.sqrt(near_cut)
    assert figures["rms_mod_fsr_over_crlb"] < 1.1  # at the bound, see the library tests

    printed, noted = run(capsys, command)
    lines = printed.splitlines()
    absolute = lines.index("absolute error (retrieved minus true frequency):")
    assert lines[absolute + 1].split()[:2] == ["method", "RMS"]
    assert lines[absolute + 2].split()[:2] == ["learned", f"{figures['rms_abs_hz'] / 1e6:.4f}"]
    modulo = next(k for k, line in enumerate(lines) if "RMS mod FSR MHz" in line)
    assert modulo > absolute + 2
    assert lines[modulo + 1].split()[:2] == ["learned", f"{figures['rms_mod_fsr_hz'] / 1e6:.4f}"]
    count = round(outside * frequency.size)
    assert noted.startswith(
        f"note: learned: {100 * outside:.3g} % of readings ({count} of {frequency.size}) lie "
        f"outside the calibrated span {low / 1e12:.3f}..{high / 1e12:.3f} THz"
    )
    assert "modulo its FSR" in noted and "--per-fsr" in noted


def test_cli_compare_rates_an_aliased_calibration_by_its_absolute_error(
    cli_files, tmp_path, capsys
):
    calibration = wm.load_calibration(cli_files["cal"])
    aliased = aliased_file(calibration, tmp_path)
    one_fsr_test = cli_files["sweep"].with_name("sweep-test.csv")
    command = f"evaluate {cli_files['cal']} {one_fsr_test} --compare {aliased}"
    report = json.loads(run(capsys, command + " --json")[0])
    figures = report["methods"]["learned (aliased.wmcal.json)"]
    frequency = np.loadtxt(one_fsr_test, delimiter=",", skiprows=1)[:, 0]
    spread = rms(frequency - calibration.center_hz_)
    assert abs(figures["rms_abs_hz"] - spread) <= ALIAS_FSR_HZ / 2  # about 15 GHz
    assert figures["rms_mod_fsr_hz"] <= ALIAS_FSR_HZ / 2
    assert figures["gross_error_fraction"] > 0.999
    assert report["methods"]["learned"]["gross_error_fraction"] == 0
    _, noted = run(capsys, command)
    assert noted.startswith("note: learned (aliased.wmcal.json): 100 % of readings (")
    assert "times shorter than the span it was calibrated on" in noted


def test_cli_says_why_a_conventional_fit_reads_the_ends_of_its_span_one_fsr_off(cli_files, capsys):
    """The conventional method fixes its FSR from the sweep's phase, shorter than the span:
    readings at the span's ends lie beyond its branch cut and are read one FSR off."""
    one_fsr_test = cli_files["sweep"].with_name("sweep-test.csv")
    command = f"evaluate {cli_files['cal']} {one_fsr_test} --sweep {cli_files['sweep']}"
    report = json.loads(run(capsys, command + " --json")[0])
    figures = report["methods"]["conventional (fitted on sweep.csv)"]
    low, high = figures["span_hz"]
    assert high - low > figures["fsr_hz"] and figures["outside_span_fraction"] == 0
    assert figures["gross_error_fraction"] > 0
    # a reading one FSR off in N lifts the RMS to at least FSR sqrt(share)
    share = figures["gross_error_fraction"]
    assert figures["rms_abs_hz"] > 0.5 * figures["fsr_hz"] * np.sqrt(share)
    assert figures["rms_mod_fsr_hz"] < figures["rms_abs_hz"]
    _, noted = run(capsys, command)
    assert noted.startswith("note: conventional (fitted on sweep.csv): ")
    assert noted.rstrip().endswith("readings near the ends of the span come back one FSR off")


@pytest.mark.slow
def test_cli_set_says_where_the_coarse_frequency_came_from(cli_files, tmp_path, capsys):
    test = np.loadtxt(cli_files["test"], delimiter=",", skiprows=1)
    fsr = wm.load_calibration(cli_files["set"]).fsr_hz_
    coarse = test[:, 0] + np.where(np.arange(len(test)) % 4 == 0, 0.6 * fsr, 0.0)
    coarse = np.where(coarse > test[:, 0].max(), test[:, 0], coarse)  # stay inside the set
    with_coarse = tmp_path / "coarse-test.csv"
    np.savetxt(
        with_coarse,
        np.column_stack([test, coarse]),
        delimiter=",",
        header="true_frequency_hz,p1_w,p2_w,p3_w,coarse_hz",
        comments="",
        fmt="%.17g",
    )
    printed, noted = run(capsys, f"evaluate {cli_files['set']} {cli_files['test']}")
    assert (
        "coarse frequency of each reading (learned per FSR calibrations): the true frequency"
        in printed
    )
    assert noted == ""
    command = f"evaluate {cli_files['set']} {with_coarse} --coarse coarse_hz"
    report = json.loads(run(capsys, command + " --json")[0])
    assert report["coarse_from"] == "coarse_hz" and report["coarse_column"] == "coarse_hz"
    assert report["methods"]["learned per FSR"]["gross_error_fraction"] == np.mean(
        coarse != test[:, 0]
    )
    printed, noted = run(capsys, command)
    assert "(learned per FSR calibrations): column coarse_hz" in printed
    assert "coarse frequency, which must lie within half an FSR of the truth" in noted


@pytest.mark.slow
def test_cli_adjacent_prints_a_table_in_plain_words(cli_files, capsys):
    command = f"evaluate {cli_files['set']} {cli_files['test']} --adjacent"
    adjacent = json.loads(run(capsys, command + " --json")[0])["adjacent"]
    printed, _ = run(capsys, command)
    assert "conventional_own" not in printed and "degradation_rms" not in printed
    lines = printed.splitlines()
    header = next(k for k, line in enumerate(lines) if "adjacent FSR RMS MHz" in line)
    assert lines[header].split()[:4] == ["method", "own", "FSR", "RMS"]
    learned, conventional = lines[header + 1].split(), lines[header + 2].split()
    assert learned == [
        "learned",
        f"{adjacent['own']['rms_hz'] / 1e6:.4f}",
        f"{adjacent['adjacent']['rms_hz'] / 1e6:.4f}",
        f"{adjacent['degradation_rms']:.3f}",
    ]
    assert conventional[0] == "conventional"
    assert float(conventional[3]) == pytest.approx(
        adjacent["conventional_adjacent"]["rms_hz"] / adjacent["conventional_own"]["rms_hz"],
        abs=5e-4,
    )
