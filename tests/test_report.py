"""The HTML report and its figures: self-contained, valid PNGs, units on every axis."""

from __future__ import annotations

import base64
import re
import subprocess
import sys
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

import wavemeter as wm
from wavemeter.report import figures as plotting
from wavemeter.report.html import report_content

from .conftest import NOISE_W, POWER_W, random_test_frequencies

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FIGURES = ("fringes", "object_space", "retrieved", "residual", "histogram")
UNIT_AT_END = re.compile(r"(\([^()]+\)|\[[^\[\]]+\])\s*$")


@dataclass(frozen=True)
class Table:
    """Stand-in for the CLI's table: the frequency is called ``x_hz`` there."""

    x_hz: np.ndarray
    powers_w: np.ndarray
    port_names: tuple[str, ...] = ("a", "b", "c")


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
    calibration = wm.Calibrator(50e9).fit(sweep.powers_w, sweep.frequency_hz)
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


@pytest.fixture(scope="module", params=["single", "set"])
def content(request, one_fsr, five_fsr, device):
    calibration, sweep, test = one_fsr if request.param == "single" else five_fsr
    return report_content(calibration, sweep, test, port_phases_rad=device.design_port_phases_rad)


def test_report_is_self_contained_html_with_valid_pngs_beside_it(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    written = wm.write_report(calibration, sweep, test, out_html=tmp_path / "chip.html")
    html_path, *pngs = written
    assert [p.name for p in pngs] == [f"chip-{name}.png" for name in FIGURES]
    assert sorted(tmp_path.iterdir()) == sorted(written)  # no temporary files left
    page = html_path.read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    sources = re.findall(r"""\b(?:src|href)\s*=\s*["']([^"']*)""", page, flags=re.IGNORECASE)
    assert len(sources) == len(FIGURES)
    assert all(source.startswith("data:image/png;base64,") for source in sources)
    assert "<script" not in page.lower() and "<link" not in page.lower()
    for source, png in zip(sources, pngs, strict=True):
        data = png.read_bytes()
        assert data.startswith(PNG_SIGNATURE)
        assert base64.b64decode(source.split(",", 1)[1]) == data
        with Image.open(png) as image:
            image.verify()
        with Image.open(png) as image:
            assert image.format == "PNG" and min(image.size) > 200


def test_report_states_the_errors_and_the_bound(one_fsr, device, tmp_path):
    calibration, sweep, test = one_fsr
    _, summary = report_content(
        calibration, sweep, test, port_phases_rad=device.design_port_phases_rad
    )
    learned, conventional = summary["methods"]["learned"], summary["methods"]["conventional"]
    # learned at the bound (a few % estimator excess, 2 % scatter over 1000 readings);
    # the conventional method an order of magnitude worse (paper Section III)
    assert 0.9 < learned["rms_hz"] / summary["crlb_rms_hz"] < 1.15
    assert conventional["rms_hz"] > 10 * learned["rms_hz"]
    page = wm.write_report(calibration, sweep, test, tmp_path / "r.html")[0].read_text()
    assert f"{learned['rms_hz'] / 1e6:.4g}" in page and "RMS / CRLB" in page


def test_every_axis_label_has_a_unit(content):
    figures, _ = content
    assert sorted(figures) == sorted(FIGURES)
    for name, figure in figures.items():
        for axes in figure.axes:
            assert UNIT_AT_END.search(axes.get_ylabel()), (name, axes.get_ylabel())
            assert axes.get_xlabel() == "" or UNIT_AT_END.search(axes.get_xlabel()), name
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
            if len(labels) >= 2:
                legend = axes.get_legend()
                assert legend is not None
                assert {text.get_text() for text in legend.get_texts()} == set(labels)
    assert methods_seen >= 3  # object space, retrieved, residual


def test_set_report_marks_the_windows_and_evaluates_the_neighbours(five_fsr, device):
    calibration, sweep, test = five_fsr
    figures, summary = report_content(
        calibration, sweep, test, port_phases_rad=device.design_port_phases_rad
    )
    top = figures["residual"].axes[0]
    assert "window edges" in top.get_legend_handles_labels()[1]
    assert set(summary["methods"]) == {"learned per FSR", "conventional per FSR"}
    assert summary["adjacent"]["windows_evaluated"] == len(calibration.windows_)


def test_conventional_calibration_is_compared_with_the_learned_one(one_fsr, device):
    _, sweep, test = one_fsr
    conventional = wm.ConventionalCalibrator(50e9, device.design_port_phases_rad)
    conventional.fit(sweep.powers_w, sweep.frequency_hz)
    _, summary = report_content(conventional, sweep, test)
    assert list(summary["methods"]) == ["conventional", "learned"]


def test_report_on_the_sweep_alone(one_fsr, tmp_path):
    calibration, sweep, _ = one_fsr
    written = wm.write_report(calibration, sweep, out_html=tmp_path / "sweep.html")
    assert "calibration sweep (501 readings)" in written[0].read_text()


def test_tables_without_frequencies_or_with_other_ports_are_refused(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    with pytest.raises(wm.InputError, match="sweep must have attributes powers_w"):
        wm.write_report(calibration, SimpleNamespace(powers_w=sweep.powers_w), None, tmp_path / "a")
    four_ports = Table(test.x_hz, np.column_stack([test.powers_w, test.powers_w[:, 0]]))
    with pytest.raises(ValueError, match="test: port powers have 4 ports but the calibration"):
        wm.write_report(calibration, sweep, four_ports, tmp_path / "b.html")
    assert list(tmp_path.iterdir()) == []


def test_set_report_refuses_test_readings_outside_the_set(five_fsr, tmp_path):
    calibration, sweep, test = five_fsr
    beyond = Table(test.x_hz + 10 * calibration.fsr_hz_, test.powers_w)
    with pytest.raises(ValueError, match="test: 1000 readings lie outside the calibration set"):
        wm.write_report(calibration, sweep, beyond, tmp_path / "r.html")


def test_missing_output_folder_writes_nothing(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    with pytest.raises(ValueError, match="folder .* does not exist"):
        wm.write_report(calibration, sweep, test, tmp_path / "missing" / "r.html")
    assert list(tmp_path.iterdir()) == []


def test_unfitted_calibration_is_refused(one_fsr, tmp_path):
    _, sweep, test = one_fsr
    with pytest.raises(wm.NotFittedError):
        wm.write_report(wm.Calibrator(), sweep, test, tmp_path / "r.html")


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


def test_import_wavemeter_does_not_import_matplotlib():
    code = (
        "import sys, wavemeter, wavemeter.report, wavemeter.report.figures; "
        "sys.exit('matplotlib' in sys.modules)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
