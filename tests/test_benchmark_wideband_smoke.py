"""Smoke test of the wide-band benchmark (benchmarks/wideband.py) in its quick mode.

The quick band (12 FSRs of 300 samples) is too small for the targets of issue 11: this
checks that the script runs, prints its tables with a PASS/FAIL column that agrees with the
numbers it prints, draws its figure, and builds its bound from the true device.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
from contextlib import redirect_stdout
from io import StringIO

import numpy as np
import pytest
from PIL import Image

import wavemeter as wm

from .helpers import BENCHMARKS

pytestmark = pytest.mark.slow

POWER_W = 1e-3
NOISE_W = 5e-7


@pytest.fixture(scope="module")
def wideband():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("wideband")


@pytest.fixture(scope="module")
def quick_run(wideband, tmp_path_factory):
    """Stdout of one quick run (asked for by the environment variable) and its figure."""
    figure = tmp_path_factory.mktemp("figure") / "wideband.png"
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(wideband.QUICK_ENV, "1")
        printed = StringIO()
        with redirect_stdout(printed):
            wideband.main(["--figure", str(figure)])
    return printed.getvalue(), figure


def _tables(text: str) -> list[list[list[str]]]:
    """Every markdown table of ``text`` as rows of stripped cells (separator rows dropped)."""
    tables, rows = [], []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            if not line.startswith("|---"):
                rows.append([cell.strip() for cell in line.strip("|").split("|")])
        elif rows:
            tables.append(rows)
            rows = []
    return tables


def _table_with(text: str, first_header: str) -> list[list[str]]:
    return next(table for table in _tables(text) if table[0][0] == first_header)


def test_quick_mode_prints_the_quick_band(wideband, quick_run):
    out, _ = quick_run
    band = wideband.QUICK_BAND
    assert f"({band.fsr_count} FSRs of 50 GHz)" in out
    assert f"{band.fsr_count} x {band.samples_per_fsr} samples" in out
    assert re.search(r"^full run: \d+ s wall clock$", out, flags=re.MULTILINE)


def test_full_band_tables_have_every_method_per_port_count(wideband, quick_run):
    out, _ = quick_run
    full = [table for table in _tables(out) if table[0] == list(wideband.FULL_HEADERS)]
    assert len(full) == len(wideband.CASES)
    for table in full:
        rows = table[1:]
        assert all(len(row) == len(wideband.FULL_HEADERS) for row in rows)
        expected = [(str(p), m) for p in wideband.PORTS for m in wideband.FULL_METHODS]
        assert [(row[0], row[1]) for row in rows] == expected


def test_targets_table_has_a_status_column_that_agrees_with_its_numbers(wideband, quick_run):
    out, _ = quick_run
    table = _table_with(out, "target (issue 11)")
    assert table[0] == [
        "target (issue 11)",
        "case",
        *(f"{p} ports" for p in wideband.PORTS),
        "status",
    ]
    rows = table[1:]
    assert len(rows) == sum(len(target.cases) for target in wideband.TARGETS)
    assert all(row[-1] in ("PASS", "FAIL") for row in rows)
    limits = {
        wideband.TARGETS[0].text: wideband.TARGET_RMS_OVER_SET,
        wideband.TARGETS[2].text: wideband.TARGET_GAP_OVER_CRLB,
    }
    checked = 0
    for row in rows:
        if row[0] in limits:
            values = [float(cell) for cell in row[2:-1]]
            assert row[-1] == ("PASS" if max(values) <= limits[row[0]] else "FAIL")
            checked += 1
        elif row[0] == wideband.TARGETS[4].text:  # fit time, "0.43 s"
            values = [float(cell.removesuffix(" s")) for cell in row[2:-1]]
            assert row[-1] == ("PASS" if max(values) < wideband.TARGET_FIT_S else "FAIL")
            checked += 1
    assert checked == 3 * len(wideband.CASES)


def test_a_coarse_value_a_fifth_of_an_fsr_off_changes_nothing(quick_run):
    """Within a quarter FSR the coarse value only picks the fringe order: the frequencies
    agree to the root finder's tolerance, far below the bound (about 10 MHz)."""
    out, _ = quick_run
    moves = re.findall(r"frequency by at most (\S+) Hz", out)
    assert len(moves) == 2
    assert all(float(move) < 1e3 for move in moves)


def test_the_figure_is_a_palette_png(quick_run):
    _, figure = quick_run
    with Image.open(figure) as image:
        assert image.format == "PNG" and image.mode == "P"
    assert [p.name for p in figure.parent.iterdir()] == [figure.name]


def test_the_bound_without_spectral_change_is_the_bound_of_one_map(wideband):
    """Without dispersion or slopes every reading has the centre's map and FSR: the
    per-reading bound is ``crlb_frequency_std`` of that one map at the delay's phase."""
    device = wm.Interferometer.table1(4, seed=2, center_hz=wideband.CENTER_HZ)
    frequency = device.center_hz + np.linspace(-2e12, 2e12, 101)
    phase = 2.0 * np.pi * (frequency - device.center_hz) * device.delay_s
    one_map = wm.crlb_frequency_std(device.true_map(), phase, POWER_W, NOISE_W, device.true_fsr_hz)
    np.testing.assert_allclose(
        wideband.wideband_crlb_hz(device, frequency, POWER_W, NOISE_W), one_map, rtol=1e-9
    )


def test_the_bound_follows_the_local_fsr(wideband):
    """With dispersion alone the phase bound is unchanged and ``df = dt / (2 pi tau_g)``:
    the bound scales with the local FSR."""
    flat = wm.Interferometer.table1(3, seed=5, center_hz=wideband.CENTER_HZ)
    dispersive = dataclasses.replace(flat, dispersion_s2=1e-26)
    frequency = flat.center_hz + np.linspace(-2e12, 2e12, 51)
    phase = dispersive.phase_rad(frequency)
    phase_bound = wm.crlb_frequency_std(flat.true_map(), phase, POWER_W, NOISE_W, 2.0 * np.pi)
    np.testing.assert_allclose(
        wideband.wideband_crlb_hz(dispersive, frequency, POWER_W, NOISE_W),
        phase_bound * dispersive.local_fsr_hz(frequency) / (2.0 * np.pi),
        rtol=1e-9,
    )


def test_held_out_readings_lie_in_the_slices_left_out(wideband):
    band = wideband.FULL_BAND
    assert (band.low_hz, band.high_hz) == pytest.approx((191.0e12, 195.4e12))
    kept = band.calibrated_slices()
    assert kept.size == 22 and np.all(kept % wideband.GAP_EVERY == 0)
    frequency = wideband.held_out_frequencies_hz(band, np.random.default_rng(0), 5000)
    slices = band.slice_index(frequency)
    assert not np.any(np.isin(slices, kept))
    assert kept[0] < slices.min() and slices.max() < kept[-1]
    # uniform over the held-out slices: each holds 1/63 of the readings, +- 5 binomial sd
    counts = np.bincount(slices, minlength=band.fsr_count)[band.held_out_slices()]
    share = 1.0 / band.held_out_slices().size
    assert np.all(np.abs(counts - 5000 * share) < 5 * np.sqrt(5000 * share * (1 - share)))


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--devices", "0"], "--devices"),
        (["--repeats", "x"], "--repeats"),
        (["--figure", "figure.svg"], "--figure"),
    ],
)
def test_bad_arguments_are_one_error_line_and_exit_code_2(wideband, capsys, argv, named):
    with pytest.raises(SystemExit) as stop:
        wideband.main(argv)
    assert stop.value.code == 2
    printed = capsys.readouterr()
    assert printed.out == ""
    lines = printed.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and named in lines[0]
