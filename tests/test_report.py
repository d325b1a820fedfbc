"""The report's figures and numbers: fit residuals, layers, legends, units, every window."""

from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.report import figures as plotting
from wavemeter.report.content import report_content
from wavemeter.report.formatting import significant
from wavemeter.report.fringes import NOISE_BAND_LABEL
from wavemeter.report.plotting import DATA_ZORDER, REFERENCE_ZORDER

from .helpers import NOISE_W, POWER_W, random_test_frequencies

FIGURES = ("fringes", "object_space", "retrieved", "residual", "histogram")
UNIT_AT_END = re.compile(r"(\([^()]+\)|\[[^\[\]]+\])\s*$")
PORTS = ("p1_dBm", "p2_dBm", "p3_dBm")


@dataclass(frozen=True)
class Table:
    """Stand-in for the CLI's table: the frequency is called ``x_hz`` there."""

    x_hz: np.ndarray
    powers_w: np.ndarray


@pytest.fixture(scope="module")
def device():
    return wm.Interferometer.table1(3, seed=8)


@pytest.fixture(scope="module")
def one_fsr(device):
    rng = np.random.default_rng(8)
    sweep_hz = device.sweep_hz(501)
    sweep = SimpleNamespace(
        frequency_hz=sweep_hz, powers_w=device.powers(sweep_hz, POWER_W, NOISE_W, rng)
    )
    test_hz = random_test_frequencies(device, 1000, rng)
    test = Table(test_hz, device.powers(test_hz, POWER_W, NOISE_W, rng))
    calibration = wm.Calibrator(50e9).fit(sweep.powers_w, sweep.frequency_hz, port_names=PORTS)
    return calibration, sweep, test


@pytest.fixture(scope="module")
def five_fsr(device):
    rng = np.random.default_rng(9)
    span = 5 * device.true_fsr_hz
    sweep_hz = device.center_hz + np.linspace(-span / 2, span / 2, 1000)
    sweep = SimpleNamespace(
        frequency_hz=sweep_hz, powers_w=device.powers(sweep_hz, POWER_W, NOISE_W, rng)
    )
    calibration = wm.CalibrationSet(50e9)
    calibration.fit(sweep.powers_w, sweep_hz)
    test_hz = rng.uniform(-span / 2, span / 2, 1000) + device.center_hz
    test = Table(test_hz, device.powers(test_hz, POWER_W, NOISE_W, rng))
    return calibration, sweep, test


@pytest.fixture(scope="module")
def single_content(one_fsr, device):
    calibration, sweep, test = one_fsr
    return report_content(calibration, sweep, test, port_phases_rad=device.design_port_phases_rad)


@pytest.fixture(scope="module")
def set_content(five_fsr, device):
    calibration, sweep, test = five_fsr
    return report_content(calibration, sweep, test, port_phases_rad=device.design_port_phases_rad)


@pytest.fixture(params=["single", "set"])
def content(request):
    return request.getfixturevalue(f"{request.param}_content")


def _marker_lines(axes):
    return [line for line in axes.get_lines() if line.get_marker() not in ("None", "", None)]


def test_report_states_the_errors_the_bound_and_the_noise(single_content, one_fsr):
    calibration = one_fsr[0]
    _, summary = single_content
    learned, conventional = summary["methods"]["learned"], summary["methods"]["conventional"]
    # learned at the bound (a few % estimator excess, 2 % scatter over 1000 readings);
    # the conventional method an order of magnitude worse (paper Section III)
    assert 0.9 < learned["rms_abs_hz"] / summary["crlb_rms_hz"] < 1.15
    assert conventional["rms_abs_hz"] > 10 * learned["rms_abs_hz"]
    assert summary["noise_std_w"] == calibration.noise_std_w_
    assert summary["noise_std_w"] == pytest.approx(NOISE_W, rel=0.1)
    assert summary["noise_from"] == "learned"


def test_fringe_residuals_are_readings_minus_the_fit_over_a_noise_band(single_content, one_fsr):
    calibration, sweep, _ = one_fsr
    top, bottom = single_content[0]["fringes"].axes
    assert top.get_ylabel() == "port power (uW)" and bottom.get_ylabel() == "residual (uW)"
    residuals = np.concatenate([line.get_ydata() for line in _marker_lines(bottom)])
    assert residuals.size == 3 * 501  # every reading of every port
    # residuals in uW scatter at the noise level: 0.5 uW, within the sampling spread
    assert np.sqrt(np.mean(residuals**2)) == pytest.approx(NOISE_W / 1e-6, rel=0.1)
    assert abs(np.mean(residuals)) < 0.05
    (band,) = bottom.patches
    low, high = band.get_y(), band.get_y() + band.get_height()
    assert (low, high) == pytest.approx((-0.5, 0.5), rel=0.1)
    assert high == pytest.approx(calibration.noise_std_w_ / 1e-6)
    assert band.get_zorder() == REFERENCE_ZORDER > DATA_ZORDER


def test_fringe_legend_names_the_ports_without_their_file_unit(single_content):
    top = single_content[0]["fringes"].axes[0]
    labels = [text.get_text() for text in top.get_legend().get_texts()]
    assert labels[:3] == ["p1", "p2", "p3"]
    assert "learned fit (lines)" in labels and NOISE_BAND_LABEL in labels
    assert not any("dBm" in label for label in labels)


def test_fit_lines_are_drawn_over_sparse_translucent_markers(single_content):
    top = single_content[0]["fringes"].axes[0]
    markers = _marker_lines(top)
    fits = [line for line in top.get_lines() if line.get_linestyle() == "-"]
    assert len(markers) == len(fits) == 3
    assert all(line.get_alpha() < 0.5 and line.get_markersize() <= 3 for line in markers)
    assert all(line.get_xdata().size <= 251 for line in markers)  # 501 readings thinned
    assert min(line.get_zorder() for line in fits) > max(line.get_zorder() for line in markers)


@pytest.mark.slow
def test_references_are_drawn_above_the_data(content):
    figures, _ = content
    data_top = max(line.get_zorder() for line in _marker_lines(figures["residual"].axes[1]))
    (crlb_band,) = figures["residual"].axes[1].collections
    assert crlb_band.get_zorder() > data_top and 0 < crlb_band.get_alpha() < 1
    for name, label in (("object_space", "correct (unit circle)"), ("retrieved", "ideal")):
        axes = figures[name].axes[0]
        (reference,) = [line for line in axes.get_lines() if line.get_label().startswith(label)]
        assert reference.get_zorder() > max(line.get_zorder() for line in _marker_lines(axes))
    histogram = figures["histogram"].axes[0]
    (normal,) = [line for line in histogram.get_lines() if "CRLB normal" in line.get_label()]
    assert normal.get_zorder() > max(patch.get_zorder() for patch in histogram.patches)


def _overlaps(first, second) -> bool:
    return (
        first.x0 < second.x1
        and second.x0 < first.x1
        and first.y0 < second.y1
        and (second.y0 < first.y1)
    )


@pytest.mark.slow
def test_legends_lie_outside_every_data_area(content):
    figures, _ = content
    legends_seen = 0
    for name, figure in figures.items():
        figure.canvas.draw()
        renderer = figure.canvas.get_renderer()
        legends = [axes.get_legend() for axes in figure.axes] + list(figure.legends)
        for legend in filter(None, legends):
            legends_seen += 1
            box = legend.get_window_extent(renderer)
            for axes in figure.axes:
                assert not _overlaps(box, axes.get_window_extent(renderer)), name
            assert box.x1 <= figure.bbox.x1 + 1 and box.y0 >= -1, (name, "legend cut")
    assert legends_seen >= 6


def test_every_axis_label_has_a_unit(content):
    figures, _ = content
    assert sorted(figures) == sorted(FIGURES)
    for name, figure in figures.items():
        for axes in figure.axes:
            assert axes.get_ylabel() == "" or UNIT_AT_END.search(axes.get_ylabel()), name
            assert axes.get_xlabel() == "" or UNIT_AT_END.search(axes.get_xlabel()), name
        assert UNIT_AT_END.search(figure.axes[0].get_ylabel()), (name, "first y label")
        assert UNIT_AT_END.search(figure.axes[-1].get_xlabel()), (name, "bottom x label")


def test_every_axes_with_two_methods_has_a_legend(content):
    figures, _ = content
    methods_seen = 0
    for figure in figures.values():
        for axes in figure.axes:
            labels = axes.get_legend_handles_labels()[1]
            methods = {label for label in labels if "learned" in label or "conventional" in label}
            if len(methods) >= 2:
                methods_seen += 1
                texts = {text.get_text() for text in axes.get_legend().get_texts()}
                assert methods <= texts
    assert methods_seen >= 3  # object space, retrieved, residual


def test_set_report_shows_every_window_as_small_multiples(set_content, five_fsr):
    calibration = five_fsr[0]
    figures, summary = set_content
    windows = len(calibration.windows_)
    assert windows == 5
    fringes = figures["fringes"]
    assert len(fringes.axes) == 2 * windows  # fringes and residual of each window
    titles = [axes.get_title() for axes in fringes.axes[0::2]]
    assert titles == [
        f"window {k}: {window.center_hz_ / 1e12:.4f} THz"
        for k, window in enumerate(calibration.windows_)
    ]
    residual_axes = fringes.axes[1::2]
    assert len({axes.get_ylim() for axes in residual_axes}) == 1  # common scale
    for axes, window in zip(residual_axes, calibration.windows_, strict=True):
        (band,) = axes.patches
        assert band.get_y() + band.get_height() == pytest.approx(window.noise_std_w_ / 1e-6)
    assert [legend.get_texts()[0].get_text() for legend in fringes.legends] == ["p1"]
    assert summary["noise_std_w"] == pytest.approx(
        np.mean([window.noise_std_w_ for window in calibration.windows_])
    )
    # the object space holds the evaluation readings of every window, not just the middle
    (learned_samples, _) = _marker_lines(figures["object_space"].axes[0])
    assert learned_samples.get_xdata().size == 1000


def test_set_report_marks_the_windows_and_evaluates_the_neighbours(set_content, five_fsr):
    calibration = five_fsr[0]
    figures, summary = set_content
    top = figures["residual"].axes[0]
    assert "window edges" in top.get_legend_handles_labels()[1]
    assert set(summary["methods"]) == {"learned per FSR", "conventional per FSR"}
    assert summary["adjacent"]["windows_evaluated"] == len(calibration.windows_)


def test_conventional_calibration_is_compared_with_the_learned_one(one_fsr, device):
    _, sweep, test = one_fsr
    conventional = wm.ConventionalCalibrator(50e9, device.design_port_phases_rad)
    conventional.fit(sweep.powers_w, sweep.frequency_hz)
    figures, summary = report_content(conventional, sweep, test)
    assert list(summary["methods"]) == ["conventional", "learned"]
    assert summary["noise_from"] == "learned"
    legend = figures["fringes"].axes[0].get_legend()
    assert "learned fit (lines)" in [text.get_text() for text in legend.get_texts()]


def test_histogram_states_the_ratio_to_the_bound_with_three_digits(single_content):
    figures, summary = single_content
    # the histogram shows each reading's error modulo the FSR (the alias nearest the truth)
    ratio = summary["methods"]["learned"]["rms_mod_fsr_hz"] / summary["crlb_rms_hz"]
    title = figures["histogram"].axes[0].get_title()
    assert title.endswith(f"RMS / CRLB {significant(ratio)}")
    rms_mhz = significant(summary["methods"]["learned"]["rms_mod_fsr_hz"] / 1e6)
    assert title.startswith(f"Error distribution, RMS {rms_mhz} MHz,")
    assert len(rms_mhz.replace(".", "").lstrip("0")) == 3


def test_error_unit_follows_the_size_of_the_errors():
    truth = np.linspace(193.3e12, 193.5e12, 50)
    small = plotting.plot_residuals(truth, {"learned": np.full(50, 2e6)}, 193.4e12, "learned")
    large = plotting.plot_residuals(
        truth,
        {"learned": np.full(50, 2e6), "conventional": np.full(50, 3e9)},
        193.4e12,
        "learned",
    )
    assert small.axes[0].get_ylabel() == "frequency error (MHz)"
    assert large.axes[0].get_ylabel() == "frequency error (GHz)"
    assert large.axes[1].get_ylabel() == "frequency error (MHz)"


@pytest.mark.slow
def test_import_wavemeter_does_not_import_matplotlib():
    code = (
        "import sys, wavemeter, wavemeter.report, wavemeter.report.figures, "
        "wavemeter.report.fringes, wavemeter.report.content, wavemeter.report.page; "
        "sys.exit('matplotlib' in sys.modules)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_fringe_fit_follows_the_monitored_source_power(device):
    """With a power monitor the map is per unit of the mean monitor reading: the fit at each
    reading scales with its monitor value, so 5 % power fluctuations leave noise alone."""
    rng = np.random.default_rng(10)
    sweep_hz = device.sweep_hz(401)
    power = POWER_W * (1 + 0.05 * rng.standard_normal(sweep_hz.size))
    sweep = SimpleNamespace(
        frequency_hz=sweep_hz,
        powers_w=device.powers(sweep_hz, power, NOISE_W, rng),
        monitor_w=power,
    )
    calibration = wm.Calibrator(50e9).fit(sweep.powers_w, sweep_hz, power_monitor_w=power)
    figures, _ = report_content(calibration, sweep)
    bottom = figures["fringes"].axes[1]
    residuals = np.concatenate([line.get_ydata() for line in _marker_lines(bottom)])
    # 5 % of a few hundred uW would be ~10 uW; the residual is the 0.5 uW noise
    assert np.sqrt(np.mean(residuals**2)) == pytest.approx(NOISE_W / 1e-6, rel=0.15)
