"""The documentation pages' walk-throughs run as written and print what the pages show.

What the README checked before the walk-throughs moved to the site: the command-line
walk-through of "Calibrate a chip from a laser sweep" is replayed command by command (every
output line the page shows, other than ``...``, must appear in what the command prints); the
wide-band and cascade examples reproduce the orders, hand-over lines and ratios their pages
quote; the frequency-noise example recovers the laser it simulates. The pages are read as
reStructuredText sources (no build needed).
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest

from wavemeter.cli import main

pytestmark = pytest.mark.slow

GUIDE = Path(__file__).parent.parent / "docs" / "user-guide"


def page(name: str) -> str:
    return (GUIDE / f"{name}.rst").read_text(encoding="utf-8")


def section(text: str, start: str, end: str) -> str:
    return text[text.index(start) : text.index(end)]


def console_commands(text: str) -> list[str]:
    """The ``$ wavemeter ...`` commands of the console blocks in ``text``, in order."""
    return [line.strip()[2:] for line in text.splitlines() if line.startswith("   $ wavemeter ")]


def run(command: str, capsys) -> list[str]:
    """Run a page's command (``wavemeter ...`` or ``head -N FILE``); its printed lines."""
    words = shlex.split(command.split(" # ")[0])
    if words[0] == "head":
        count = int(words[1].lstrip("-"))
        return Path(words[2]).read_text().splitlines()[:count]
    assert words[0] == "wavemeter"
    code = main(words[1:])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    return (printed.out + printed.err).splitlines()


def walk_through() -> tuple[str, list[tuple[str, list[str]]]]:
    """The command that makes the example files, and each ``$ command`` with its output."""
    text = page("sweep")
    setup = re.search(r"``(wavemeter simulate -o scan\.csv[^`]*)``", text).group(1)
    steps, current = [], None
    for line in section(text, "The walk-through", "The same in Python").splitlines():
        if line.startswith("   $ "):
            current = (line[5:], [])
            steps.append(current)
        elif current is not None and line.startswith("   ") and line.strip():
            current[1].append(line[3:])
        else:
            current = None
    return " ".join(setup.split()), steps


def test_the_walk_through_prints_what_the_page_shows(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    setup, steps = walk_through()
    run(setup, capsys)
    assert [command.split()[:2] for command, _ in steps] == [
        ["wavemeter", "calibrate"],
        ["wavemeter", "measure"],
        ["head", "-2"],
        ["wavemeter", "evaluate"],
    ]
    for command, expected in steps:
        printed = run(command, capsys)
        for line in expected:
            if line.strip() != "...":
                assert line in printed, f"{command}: line on the page not printed: {line!r}"


def test_the_noise_example_recovers_the_laser_it_simulates(tmp_path, monkeypatch):
    """The frequency-noise page's Python example recovers the simulated laser's linewidth
    and drift within 3 of their stated standard deviations."""
    monkeypatch.chdir(tmp_path)
    text = section(page("noise"), "In Python", "What the analysis may say")
    code = re.search(r"\.\. code-block:: python\n\n((?:   .*\n|\n)+)", text).group(1)
    code = "\n".join(line[3:] for line in code.splitlines())
    namespace: dict = {}
    exec(compile(code, "noise.rst", "exec"), namespace)  # noqa: S102 - the page's own code
    result = namespace["result"]
    assert not result.linewidth_is_upper_limit
    assert abs(result.lorentzian_linewidth_hz - 500e6) < 3 * result.lorentzian_linewidth_std_hz
    assert abs(result.drift_hz_per_s - 1e9) < 3 * result.drift_std_hz_per_s


def test_the_wide_band_example_chooses_the_orders_the_page_states(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    text = section(page("wideband"), "On the command line", "- ``simulate --spectral sin``")
    simulate, calibrate = console_commands(text)[:2]
    run(simulate, capsys)
    run(calibrate, capsys)
    prose = " ".join(text.split())
    orders = re.search(r"chose phase order (\d) and map order (\d)", prose)
    info = "\n".join(run("wavemeter info band.wmcal.json", capsys))
    assert re.search(rf"^phase order P\s+{orders.group(1)}$", info, re.M)
    assert re.search(rf"^map order J\s+{orders.group(2)}$", info, re.M)
    stated = re.search(r"fell from (\S+) MHz .*? to (\S+) MHz", prose)
    candidates = {
        (candidate["phase_order"], candidate["map_order"]): candidate["cv_rms_hz"] / 1e6
        for candidate in json.loads(Path("band.wmcal.json").read_text())["diagnostics"]["wideband"][
            "orders"
        ]["candidates"]
    }
    chosen = (int(orders.group(1)), int(orders.group(2)))
    assert f"{candidates[(1, 0)]:.3g}" == stated.group(1)
    assert f"{candidates[chosen]:.3g}" == stated.group(2)
    printed = run("wavemeter evaluate band.wmcal.json band-test.csv", capsys)
    row = next(line for line in printed if line.startswith("wideband "))
    # 3000 test readings: the RMS over the bound is 1 within 4 / sqrt(2 x 3000) = 0.05
    assert abs(float(row.split()[-1]) - 1.0) < 0.05


def test_the_cascade_example_prints_what_the_page_states(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    text = section(page("cascade"), "On the command line", "- ``simulate --cascade``")
    design, simulate, calibrate = console_commands(text)[:3]
    prose = " ".join(text.split())
    printed = run(design, capsys)
    stated = re.search(r"three stages, (\S+) THz / (\S+) GHz / 50 GHz", prose)
    fsrs_ghz = [line.split()[1] for line in printed[1:4]]
    assert [f"{float(fsrs_ghz[0]) / 1e3:.3g}", f"{float(fsrs_ghz[1]):.3g}"] == list(stated.groups())
    assert fsrs_ghz[2] == "50" and printed[4].startswith("band:")
    run(simulate, capsys)
    run(calibrate, capsys)
    info = run("wavemeter info cband.wmcal.json", capsys)
    quoted = text[text.index("   hand-overs:") :].split("\n\n")[0].split("\n")
    assert len(quoted) == 4 and sum("stage " in line for line in quoted) == 2
    for line in quoted:
        assert line[3:] in info
    evaluated = run("wavemeter evaluate cband.wmcal.json cband-test.csv", capsys)
    row = next(line for line in evaluated if line.startswith("cascade "))
    ratio = re.search(r"(\S+) MHz RMS, (\S+)x the Cramer-Rao bound", prose)
    assert f"{float(row.split()[1]):.3g}" == ratio.group(1) and row.split()[-1] == ratio.group(2)
    assert any("0 of 5000 readings off" in line for line in evaluated)


def test_the_plugin_page_shows_the_toy_plugin_packages_entry_points():
    """The page's pyproject excerpt is the tested plug-in package's, not a paraphrase."""
    import tomllib

    page = (GUIDE / "custom-calibrator.rst").read_text(encoding="utf-8")
    block = page.split(".. code-block:: toml\n", 1)[1].split("\n\n", 1)[1]
    lines = []
    for line in block.splitlines():
        if line and not line.startswith("   "):
            break
        lines.append(line[3:])
    shown = tomllib.loads("\n".join(lines))
    toy = Path(__file__).parent / "plugins" / "wavemeter_toy" / "pyproject.toml"
    tested = tomllib.loads(toy.read_text(encoding="utf-8"))
    group = "wavemeter.calibrators"
    assert shown["project"]["entry-points"][group] == tested["project"]["entry-points"][group]
    assert shown["tool"] == tested["tool"]
