"""The report in a real browser: headless Chromium loads every figure, logs no error.

A copy of the page gets a small probe script (the report itself has none) that records
errors and, after the load event, each image's natural size and the page width into the
DOM, which ``--dump-dom`` prints. The unmodified page is also loaded with console logging
on: it must not log anything. Skipped where ``chromium`` is not installed.
"""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

import wavemeter as wm
from wavemeter.report.html import report_paths

from .helpers import NOISE_W, POWER_W, random_test_frequencies

CHROMIUM = shutil.which("chromium")
pytestmark = [
    pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed"),
    pytest.mark.slow,  # a real browser
]

FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--hide-scrollbars",
    "--window-size=1200,900",
)
WIDTH_PX = 1200
PROBE = """<script>
(() => {
  const errors = [];
  addEventListener("error", (event) => {
    const source = event.target && event.target.src;
    errors.push(source ? "failed to load " + source.slice(0, 40) : String(event.message));
  }, true);
  for (const level of ["error", "warn"]) {
    const original = console[level];
    console[level] = (...args) => {
      errors.push(level + ": " + args.join(" "));
      original(...args);
    };
  }
  addEventListener("load", () => {
    const images = [...document.images].map((image) => ({
      complete: image.complete,
      naturalWidth: image.naturalWidth,
      naturalHeight: image.naturalHeight,
      shownWidth: image.getBoundingClientRect().width,
    }));
    const state = {images, errors, scrollWidth: document.documentElement.scrollWidth};
    document.body.setAttribute("data-probe", JSON.stringify(state));
  });
})();
</script>"""


def _chromium(arguments: list[str], profile: Path) -> subprocess.CompletedProcess:
    result = subprocess.run(
        [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *arguments],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    return result


def probe_page(page: Path, folder: Path) -> dict:
    """What the browser saw: images (natural and shown size), errors, page width."""
    probed = folder / f"probed-{page.name}"
    probed.write_text(page.read_text(encoding="utf-8").replace("<head>", "<head>" + PROBE, 1))
    dom = _chromium(["--dump-dom", probed.resolve().as_uri()], folder / "profile").stdout
    found = re.search(r'data-probe="([^"]*)"', dom)
    assert found, "the probe did not run: " + dom[:500]
    return json.loads(html.unescape(found.group(1)))


def console_messages(page: Path, folder: Path) -> list[str]:
    """Console lines Chromium logged while loading the unmodified page."""
    result = _chromium(
        ["--enable-logging=stderr", "--v=0", "--dump-dom", page.resolve().as_uri()],
        folder / "profile",
    )
    return [line for line in result.stderr.splitlines() if ":CONSOLE" in line]


@pytest.fixture(scope="module")
def reports(tmp_path_factory) -> dict[str, Path]:
    """A single-calibration report and a two-window calibration-set report."""
    folder = tmp_path_factory.mktemp("browser")
    device = wm.Interferometer.table1(3, seed=4)
    rng = np.random.default_rng(4)
    sweep_hz = device.sweep_hz(401)
    sweep = SimpleNamespace(
        frequency_hz=sweep_hz, powers_w=device.powers(sweep_hz, POWER_W, NOISE_W, rng)
    )
    test_hz = random_test_frequencies(device, 600, rng)
    test = SimpleNamespace(
        frequency_hz=test_hz, powers_w=device.powers(test_hz, POWER_W, NOISE_W, rng)
    )
    single = wm.Calibrator(50e9).fit(sweep.powers_w, sweep_hz)
    span = 2 * device.true_fsr_hz
    wide_hz = device.center_hz + np.linspace(-span / 2, span / 2, 600)
    wide = SimpleNamespace(
        frequency_hz=wide_hz, powers_w=device.powers(wide_hz, POWER_W, NOISE_W, rng)
    )
    calibration_set = wm.CalibrationSet(50e9).fit(wide.powers_w, wide_hz)
    return {
        "single": wm.write_report(single, sweep, test, folder / "single.html")[0],
        "set": wm.write_report(calibration_set, wide, None, folder / "set.html")[0],
    }


def test_the_probe_sees_a_broken_image_and_a_console_error(tmp_path):
    page = tmp_path / "broken.html"
    page.write_text(
        '<!DOCTYPE html><html><head></head><body><img src="data:image/png;base64,AAAA">'
        '<script>console.error("boom")</script></body></html>'
    )
    state = probe_page(page, tmp_path)
    assert [image["naturalWidth"] for image in state["images"]] == [0]
    assert "error: boom" in state["errors"]
    assert any('"boom"' in line for line in console_messages(page, tmp_path))


@pytest.mark.parametrize("kind", ["single", "set"])
def test_every_figure_loads_and_fits_the_page(reports, kind, tmp_path):
    page = reports[kind]
    state = probe_page(page, tmp_path)
    assert state["errors"] == []
    assert len(state["images"]) == 5
    for image, png in zip(state["images"], report_paths(page)[1:], strict=True):
        assert image["complete"]
        with Image.open(png) as figure:  # the PNG beside the page, the same figure
            assert (image["naturalWidth"], image["naturalHeight"]) == figure.size
        assert 0 < image["shownWidth"] <= WIDTH_PX
    assert state["scrollWidth"] <= WIDTH_PX  # nothing wider than the window: no cut content


@pytest.mark.parametrize("kind", ["single", "set"])
def test_the_page_logs_nothing_to_the_console(reports, kind, tmp_path):
    assert console_messages(reports[kind], tmp_path) == []
