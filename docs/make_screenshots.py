"""Render the README's report screenshots: docs/report-single.png and docs/report-set.png.

Runs the README walk-through in a temporary folder (a lab-like 1-FSR sweep in nm and dBm,
and a 5-FSR sweep calibrated per FSR), writes both reports and takes full-page
screenshots with headless Chromium, 1200 px wide, reduced to a 256-colour palette.

    .venv/bin/python docs/make_screenshots.py
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image

from wavemeter.cli import main

DOCS = Path(__file__).resolve().parent
WIDTH_PX = 1200
COLOURS = 256
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--hide-scrollbars",
)
HEIGHT_PROBE = (
    '<script>addEventListener("load", () => document.body.setAttribute('
    '"data-height", document.documentElement.scrollHeight))</script>'
)
COMMANDS = {
    "report-single.png": [
        "simulate -o scan.csv --x-unit nm --power-unit dBm --noise-w 2e-8 --test 5000",
        "calibrate scan.csv -o chip.wmcal.json --fsr 50GHz",
        "report chip.wmcal.json scan.csv scan-test.csv -o report.html",
    ],
    "report-set.png": [
        "simulate -o wide.csv --span-fsr 5 --samples 5001 --test 5000",
        "calibrate wide.csv -o set.wmcal.json --per-fsr",
        "report set.wmcal.json wide.csv wide-test.csv -o set.html",
    ],
}


def _chromium(browser: str, profile: Path, *arguments: str) -> str:
    result = subprocess.run(
        [browser, *FLAGS, f"--user-data-dir={profile}", *arguments],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return result.stdout


def screenshot(browser: str, page: Path, out: Path, folder: Path) -> None:
    """A full-page screenshot of ``page``, ``WIDTH_PX`` wide, as a palette PNG."""
    probed = folder / f"height-{page.name}"
    probed.write_text(page.read_text(encoding="utf-8").replace("<head>", "<head>" + HEIGHT_PROBE))
    dom = _chromium(
        browser, folder / "profile", f"--window-size={WIDTH_PX},900", "--dump-dom", probed.as_uri()
    )
    height = int(re.search(r'data-height="(\d+)"', dom).group(1))
    raw = folder / "raw.png"
    _chromium(
        browser,
        folder / "profile",
        f"--window-size={WIDTH_PX},{height}",
        f"--screenshot={raw}",
        page.as_uri(),
    )
    with Image.open(raw) as image:
        palette = image.convert("RGB").quantize(COLOURS, dither=Image.Dither.NONE)
        palette.save(out, optimize=True)


def run() -> None:
    browser = shutil.which("chromium")
    if browser is None:
        sys.exit("chromium is not installed")
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        os.chdir(folder)
        for target, commands in COMMANDS.items():
            for command in commands:
                if main(shlex.split(command + " --quiet")) != 0:
                    sys.exit(f"failed: wavemeter {command}")
            page = folder / commands[-1].split("-o ")[1]
            screenshot(browser, page, DOCS / target, folder)
            print(f"wrote {DOCS / target} ({(DOCS / target).stat().st_size // 1024} kB)")


if __name__ == "__main__":
    run()
