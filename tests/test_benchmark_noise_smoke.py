"""Smoke test of the frequency-noise benchmark (benchmarks/noise.py) on short records."""

from __future__ import annotations

import contextlib
import importlib
import io

import numpy as np
import pytest
from PIL import Image

from .helpers import BENCHMARKS, table_rows

pytestmark = pytest.mark.slow

#: readings of a short record (3.3 ms at 10 MHz)
SAMPLES = 2**15


@pytest.fixture(scope="module")
def noise():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("noise")


@pytest.fixture(scope="module")
def printed(noise, tmp_path_factory):
    """Stdout of a whole run: one seed of 2^14 readings per laser."""
    folder = tmp_path_factory.mktemp("figures")
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        noise.main(["--seeds", "1", "--samples", str(2**14), "--figures", str(folder)])
    return out.getvalue(), folder


def _table(text: str, headers) -> list[list[str]]:
    """The markdown table of ``text`` with the header row ``headers``."""
    for block in text.split("\n\n"):
        if block.startswith("| "):
            rows = table_rows(block)
            if rows[0] == list(headers):
                return rows
    raise AssertionError(f"no table with the headers {headers}")


def test_a_run_prints_every_table_a_verdict_and_the_wall_clock(noise, printed):
    text, folder = printed
    titles = [case.title for case in noise.CASES]
    linewidth = _table(text, noise.LINEWIDTH_HEADERS)
    assert [row[0] for row in linewidth[2:]] == titles
    assert all(row[-1] in ("PASS", "FAIL", "n/a") for row in linewidth[2:])
    deviations = _table(text, noise.DEVIATION_HEADERS)
    assert [row[1] for row in deviations[2:]] == ["ADEV", "MDEV"] * len(titles)
    assert all(row[-1] in ("PASS", "FAIL") for row in deviations[2:])
    for headers in (noise.EXTRA_HEADERS, noise.SIDE_LINEWIDTH_HEADERS):
        assert [row[0] for row in _table(text, headers)[2:]] == titles
    assert {row[0] for row in _table(text, noise.SIDE_ADEV_HEADERS)[2:]} == set(titles)
    assert len(_table(text, noise.FLOOR_HEADERS)) - 2 == 1
    check = _table(text, noise.CHECK_HEADERS)
    assert len(check) - 2 == 3 * (len(noise.CHECK_KINDS) + 1)
    verdict = [line for line in text.splitlines() if line.startswith(("PASS ", "FAIL "))]
    assert len(verdict) == 7
    assert text.rstrip().splitlines()[-1].endswith("s wall clock")
    assert sorted(p.name for p in folder.iterdir()) == sorted([noise.ADEV_FIGURE, noise.PSD_FIGURE])
    for path in folder.iterdir():
        with Image.open(path) as image:
            assert image.format == "PNG" and image.mode == "P"


def test_a_wide_white_laser_is_measured_within_its_stated_uncertainty(noise):
    """10 MHz of white FM is 800x the meter's floor: a number, with the truth within 3 of
    its stated standard deviations (a 0.3 % chance to fail by chance)."""
    run = noise.measure(noise.CASE_BY_KEY["white_10M"], seed=1, samples=SAMPLES)
    assert run.white_over_floor > 100
    assert not run.noise.linewidth_is_upper_limit
    assert abs(run.linewidth_error_hz) <= 3.0 * run.noise.lorentzian_linewidth_std_hz
    assert run.unwrapped


def test_by_hand_on_the_meters_readings_the_white_level_holds_the_floor(noise):
    """A script's Welch white level of the meter's readings is the laser's plus the meter's
    true floor: the band mean over 0.1-0.45 of the rate of one 2^14-point Welch estimate
    (3 segments) averages about 5700 bins x 3 segments (relative standard error < 1 %)."""
    run = noise.measure(noise.CASE_BY_KEY["white_1k"], seed=1, samples=SAMPLES)
    expected = run.case.white_fm_hz2_per_hz + run.true_floor_hz2_per_hz
    assert run.hand_meter_white_hz2_per_hz == pytest.approx(expected, rel=0.05)
    assert run.hand_true_white_hz2_per_hz == pytest.approx(run.case.white_fm_hz2_per_hz, rel=0.05)
    assert run.hand_meter_white_hz2_per_hz > 5 * run.case.white_fm_hz2_per_hz


def test_a_laser_below_the_floor_is_an_upper_limit_above_the_truth(noise):
    run = noise.measure(noise.CASE_BY_KEY["white_1k"], seed=2, samples=SAMPLES)
    assert run.white_over_floor < 1
    assert run.noise.linewidth_is_upper_limit
    assert run.within_stated()
    target, ok = noise.linewidth_target([run])
    assert ok and target.startswith("upper limit")


def test_the_unwrapped_drift_across_two_fsrs_follows_the_truth(noise):
    """10 GHz/s over 3.3 ms is 33 MHz; the full benchmark's 0.1 s crosses two FSRs."""
    run = noise.measure(noise.CASE_BY_KEY["drift"], seed=1, samples=SAMPLES)
    assert run.unwrapped
    assert abs(run.noise.drift_hz_per_s - 1e10) <= 3.0 * run.noise.drift_std_hz_per_s


def test_the_analytic_check_holds_where_it_is_exact(noise):
    """White FM and a drift have no small-m departure: allantools on 2^16 readings within a
    few of the estimator's standard errors (ADEV at m = 1: about 1/sqrt(2 N) = 0.3 %)."""
    ratios = noise.analytic_check(2**16, seed=1)
    assert ratios[("white FM", "adev")][0] == pytest.approx(1.0, abs=0.02)
    assert ratios[("white FM", "hdev")][0] == pytest.approx(1.0, abs=0.02)
    assert np.allclose(ratios[("drift", "adev")], 1.0, rtol=1e-6)
    assert np.allclose(ratios[("drift", "mdev")], 1.0, rtol=1e-3)


@pytest.mark.parametrize(
    ("argv", "named"),
    [(["--seeds", "0"], "--seeds"), (["--samples", "100"], "--samples")],
)
def test_bad_arguments_are_one_error_line_and_exit_code_2(noise, capsys, argv, named):
    with pytest.raises(SystemExit) as stop:
        noise.main(argv)
    assert stop.value.code == 2
    printed = capsys.readouterr()
    assert printed.out == ""
    lines = printed.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and named in lines[0]


def test_an_unwritable_figure_folder_is_one_error_line(noise, capsys, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(SystemExit) as stop:
        noise.main(["--figures", str(blocker)])
    assert stop.value.code == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "--figures" in lines[0]


def test_a_noise_free_drifting_laser_gets_no_positive_beta_number(noise):
    """No frequency noise of its own: only the meter's floor scatters about the beta line,
    so the beta-line linewidth is an upper limit, or 0 when the PSD stays under the line
    (as in this short record, whose lowest band, 3.7 kHz, puts the line near the floor);
    either way the truth, 0, is judged within."""
    run = noise.measure(noise.CASE_BY_KEY["drift"], seed=1, samples=SAMPLES)
    assert run.model_beta_linewidth_hz == 0
    assert run.noise.beta_linewidth_is_upper_limit or run.noise.beta_linewidth_hz == 0
    assert run.beta_within_stated()
