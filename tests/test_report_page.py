"""The report's page and files: header, numbers, citation, safe outputs, the CLI command."""

from __future__ import annotations

import base64
import re
import shlex
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

import wavemeter as wm
from wavemeter.cli import main
from wavemeter.report.content import report_content
from wavemeter.report.formatting import port_label, significant
from wavemeter.report.html import report_paths
from wavemeter.report.page import PAPER_CITATION

from .helpers import NOISE_W, POWER_W, random_test_frequencies

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FIGURES = ("fringes", "object_space", "retrieved", "residual", "histogram")


@dataclass(frozen=True)
class Table:
    """A table as the readers return it: frequencies in ``x_hz`` and its file in ``source``."""

    x_hz: np.ndarray
    powers_w: np.ndarray
    source: Path


@pytest.fixture(scope="module")
def one_fsr(tmp_path_factory):
    device = wm.Interferometer.table1(3, seed=8)
    rng = np.random.default_rng(8)
    folder = tmp_path_factory.mktemp("inputs")
    sweep_hz = device.sweep_hz(301)
    sweep = Table(sweep_hz, device.powers(sweep_hz, POWER_W, NOISE_W, rng), folder / "scan.csv")
    test_hz = random_test_frequencies(device, 500, rng)
    test = Table(test_hz, device.powers(test_hz, POWER_W, NOISE_W, rng), folder / "scan-test.csv")
    for table in (sweep, test):
        table.source.write_text("stand-in for the file the table was read from\n")
    calibration = wm.Calibrator(50e9).fit(sweep.powers_w, sweep.x_hz)
    return calibration, sweep, test


@pytest.fixture(scope="module")
def written(one_fsr, tmp_path_factory):
    calibration, sweep, test = one_fsr
    out = tmp_path_factory.mktemp("report") / "chip.html"
    paths = wm.write_report(
        calibration, sweep, test, out, input_files={"calibration": "chip.wmcal.json"}
    )
    return paths, paths[0].read_text(encoding="utf-8")


def _cells(page: str, name: str) -> str:
    """The text of the table cell after the cell holding ``name``."""
    found = re.search(rf"<td>{re.escape(name)}</td><td>([^<]*)</td>", page)
    assert found, name
    return found.group(1)


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (1.002, "1.00"),
        (0.98765, "0.988"),
        (0.38742, "0.387"),
        (309.58, "310"),
        (3512.4, "3510"),
        (9.996, "10.0"),
        (-0.0123456, "-0.0123"),
        (0.0, "0.00"),
        (float("nan"), "nan"),
    ],
)
def test_numbers_keep_three_significant_digits(value, text):
    assert significant(value) == text


@pytest.mark.parametrize(
    ("name", "label"),
    [
        ("p1_dBm", "p1"),
        ("Port 3 [uW]", "Port 3"),
        ("P2_mW", "P2"),
        ("DC CH1", "DC CH1"),
        ("p4", "p4"),
    ],
)
def test_port_labels_drop_the_file_unit_only(name, label):
    assert port_label(name) == label


@pytest.mark.slow
def test_page_is_self_contained_with_valid_pngs_beside_it(written):
    paths, page = written
    html_path, *pngs = paths
    assert [p.name for p in pngs] == [f"chip-{name}.png" for name in FIGURES]
    assert sorted(html_path.parent.iterdir()) == sorted(paths)  # no temporary files left
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    sources = re.findall(r"""\b(?:src|href)\s*=\s*["']([^"']*)""", page, flags=re.IGNORECASE)
    assert len(sources) == len(FIGURES)
    assert "<script" not in page.lower() and "<link" not in page.lower()
    for source, png in zip(sources, pngs, strict=True):
        data = png.read_bytes()
        assert data.startswith(PNG_SIGNATURE)
        assert base64.b64decode(source.split(",", 1)[1]) == data
        with Image.open(png) as image:
            assert image.format == "PNG" and image.size[0] == 900  # 9 in at 100 dpi


def test_header_names_inputs_noise_retrieval_method_fsr_and_version(written, one_fsr):
    calibration, sweep, test = one_fsr
    _, page = written
    assert _cells(page, "calibration file") == "chip.wmcal.json"
    assert _cells(page, "sweep") == str(sweep.source)
    assert _cells(page, "test") == str(test.source)
    assert _cells(page, "wavemeter version") == wm.__version__
    assert _cells(page, "method") == "learned"
    assert _cells(page, "phase retrieval").startswith("pinv: x = A⁺ p")
    assert _cells(page, "fitted FSR (GHz)") == f"{calibration.fsr_hz_ / 1e9:.9g}"
    noise = _cells(page, "detector noise estimate (W)")
    assert noise == f"{calibration.noise_std_w_:.2e} (learned fit residual)"


def test_error_table_gives_ratios_to_the_bound_with_three_digits(written, one_fsr):
    calibration, sweep, test = one_fsr
    _, page = written
    _, summary = report_content(calibration, sweep, test)
    learned = summary["methods"]["learned"]
    # within its FSR the learned calibration is at the bound; absolute, the test readings
    # beyond the one-FSR sweep come back an FSR off (the share in the last column)
    ratio = significant(learned["rms_mod_fsr_hz"] / summary["crlb_rms_hz"])
    assert re.fullmatch(r"\d\.\d\d", ratio)  # e.g. 1.00 or 0.98, never "1"
    absolute = significant(learned["rms_abs_hz"] / summary["crlb_rms_hz"])
    row = f"<td>learned</td><td>{significant(learned['rms_abs_hz'] / 1e6)}</td>"
    mod_fsr = f"<td>{significant(learned['rms_mod_fsr_hz'] / 1e6)}</td><td>{ratio}</td>"
    assert row in page and f"<td>{absolute}</td>{mod_fsr}" in page
    assert "<td>CRLB</td>" in page and "<td>1.00</td><td></td><td></td><td></td></tr>" in page


def test_captions_cite_the_paper_in_full(written):
    _, page = written
    assert "[1], Fig. 4b and 7a" in page and "paper Fig" not in page
    assert "G. M. Hasan, M. Hasan, P. Liu, M. Rad, E. Bernier and T. J. Hall" in PAPER_CITATION
    assert "Optical Wavelength Meter with Machine Learning Enhanced Precision" in PAPER_CITATION
    assert f"[1] {PAPER_CITATION}" in page


@pytest.mark.slow
def test_header_shows_the_calibration_diagnostics_when_it_has_them(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    diagnosed = wm.Calibrator(50e9).fit(sweep.powers_w, sweep.x_hz)
    diagnosed.diagnostics_ = {
        "fsr_estimate_hz": 49.61e9,
        "ports": [
            {"name": "p1", "status": "ok", "noise_std_w": 5.01e-7, "fringe_z": 6220.1},
            {"name": "p2", "status": "dead", "noise_std_w": 4.98e-7, "fringe_z": 1.23456},
        ],
        "warnings": [{"cause": "dead_port", "message": "port p2 shows no fringe", "remedy": "fix"}],
    }
    page = wm.write_report(diagnosed, sweep, test, tmp_path / "r.html")[0].read_text()
    assert "<h2>Diagnostics of the calibration</h2>" in page
    assert "<td>fsr estimate (GHz)</td><td>49.6</td>" in page
    assert "<td>warning (dead_port)</td><td>port p2 shows no fringe fix</td>" in page
    header = "<tr><th>name</th><th>status</th><th>noise std (W)</th><th>fringe z</th></tr>"
    assert header + "<tr><td>p1</td><td>ok</td><td>5.01e-07</td><td>6220</td></tr>" in page
    assert "<tr><td>p2</td><td>dead</td><td>4.98e-07</td><td>1.23</td></tr>" in page


@pytest.mark.slow
def test_the_diagnostics_a_fit_records_are_shown_and_none_without_them(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    fitted = wm.Calibrator(50e9).fit(sweep.powers_w, sweep.x_hz)
    page = wm.write_report(fitted, sweep, test, tmp_path / "with.html")[0].read_text()
    assert fitted.diagnostics_ and "<h2>Diagnostics of the calibration</h2>" in page
    for name in fitted.port_names_:
        assert f"<tr><td>{name}</td>" in page  # one row per port of the health table
    fitted.diagnostics_ = None
    page = wm.write_report(fitted, sweep, test, tmp_path / "without.html")[0].read_text()
    assert "Diagnostics" not in page


@pytest.mark.slow
def test_an_existing_output_is_kept_unless_forced(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    out = tmp_path / "r.html"
    stale = tmp_path / "r-histogram.png"
    stale.write_bytes(b"an older figure")
    with pytest.raises(wm.InputError, match="r-histogram.png already exists") as error:
        wm.write_report(calibration, sweep, test, out)
    assert error.value.parameter == "force"
    assert sorted(tmp_path.iterdir()) == [stale]  # checked before anything was written
    assert stale.read_bytes() == b"an older figure"
    paths = wm.write_report(calibration, sweep, test, out, force=True)
    assert stale.read_bytes().startswith(PNG_SIGNATURE)
    assert sorted(tmp_path.iterdir()) == sorted(paths)


def test_an_output_that_is_an_input_is_refused(one_fsr):
    calibration, sweep, test = one_fsr
    before = sweep.source.read_text()
    with pytest.raises(wm.InputError, match="it is the input file"):
        wm.write_report(calibration, sweep, test, sweep.source, force=True)
    assert sweep.source.read_text() == before


def test_standard_output_and_unknown_input_roles_are_refused(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    with pytest.raises(wm.InputError, match="cannot go to standard output") as error:
        wm.write_report(calibration, sweep, test, "-")
    assert error.value.parameter == "out_html"
    with pytest.raises(wm.InputError, match="unknown roles"):
        wm.write_report(calibration, sweep, test, tmp_path / "r.html", input_files={"cal": "x"})
    assert list(tmp_path.iterdir()) == []


def test_report_paths_are_the_page_then_one_png_per_figure():
    assert [path.name for path in report_paths("out/r.html")] == ["r.html"] + [
        f"r-{name}.png" for name in FIGURES
    ]


def test_tables_without_frequencies_or_with_other_ports_are_refused(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    with pytest.raises(wm.InputError, match="sweep must have attributes powers_w"):
        wm.write_report(calibration, SimpleNamespace(powers_w=sweep.powers_w), None, tmp_path / "a")
    four_ports = Table(test.x_hz, np.column_stack([test.powers_w, test.powers_w[:, 0]]), Path("t"))
    with pytest.raises(wm.InputError, match="test: port powers have 4 ports but the calibration"):
        wm.write_report(calibration, sweep, four_ports, tmp_path / "b.html")
    assert list(tmp_path.iterdir()) == []


def test_set_report_refuses_test_readings_outside_the_set(tmp_path):
    device = wm.Interferometer.table1(3, seed=9)
    span = 2 * device.true_fsr_hz
    sweep_hz = device.center_hz + np.linspace(-span / 2, span / 2, 400)
    powers = device.powers(sweep_hz, POWER_W, NOISE_W, 9)
    calibration = wm.CalibrationSet(50e9).fit(powers, sweep_hz)
    sweep = SimpleNamespace(frequency_hz=sweep_hz, powers_w=powers)
    beyond = SimpleNamespace(frequency_hz=sweep_hz + 10 * calibration.fsr_hz_, powers_w=powers)
    with pytest.raises(
        wm.InputError, match="test: the calibration cannot read any of the 400 readings"
    ):
        wm.write_report(calibration, sweep, beyond, tmp_path / "r.html")


@pytest.mark.slow
def test_report_on_the_sweep_alone(one_fsr, tmp_path):
    calibration, sweep, _ = one_fsr
    page = wm.write_report(calibration, sweep, out_html=tmp_path / "sweep.html")[0].read_text()
    assert "calibration sweep (301 readings)" in page
    assert "<td>test</td><td>none: evaluated on the sweep</td>" in page


def test_missing_output_folder_writes_nothing(one_fsr, tmp_path):
    calibration, sweep, test = one_fsr
    with pytest.raises(wm.InputError, match="folder .* does not exist"):
        wm.write_report(calibration, sweep, test, tmp_path / "missing" / "r.html")
    assert list(tmp_path.iterdir()) == []


def test_unfitted_calibration_is_refused(one_fsr, tmp_path):
    _, sweep, test = one_fsr
    with pytest.raises(wm.NotFittedError):
        wm.write_report(wm.Calibrator(), sweep, test, tmp_path / "r.html")


@pytest.mark.slow
def test_cli_report_replaces_outputs_only_with_force(tmp_path, capsys):
    sweep, cal, out = tmp_path / "scan.csv", tmp_path / "chip.wmcal.json", tmp_path / "r.html"
    assert main(shlex.split(f"simulate -o {sweep} --samples 301 --test 300 --quiet")) == 0
    assert main(shlex.split(f"calibrate {sweep} -o {cal} --quiet")) == 0
    test = tmp_path / "scan-test.csv"
    command = f"report {cal} {sweep} {test} -o {out}"
    assert main(shlex.split(command)) == 0
    page = out.read_text()
    assert f"<td>calibration file</td><td>{cal}</td>" in page
    assert f"<td>sweep</td><td>{sweep}</td>" in page and f"<td>test</td><td>{test}</td>" in page
    capsys.readouterr()
    assert main(shlex.split(command)) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "already exists" in err and "--force" in err
    assert len(err.strip().splitlines()) == 1
    assert out.read_text() == page
    assert main(shlex.split(command + " --force --quiet")) == 0
    assert main(shlex.split(f"report {cal} {sweep} -o {sweep} --force")) == 2
    assert "is the input file" in capsys.readouterr().err
    assert sweep.read_text().startswith("frequency_hz")
