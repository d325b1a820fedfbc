"""The README's examples run as written and print what the README shows.

The walk-through of "Using your own data" is replayed command by command: every output line
the README shows (other than ``...``) must appear in what the command prints. The Python
example runs as it stands.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest

from wavemeter.cli import main

README = (Path(__file__).parent.parent / "README.md").read_text(encoding="utf-8")


def walk_through() -> tuple[str, list[tuple[str, list[str]]]]:
    """The command that makes the example files, and each ``$ command`` with its output."""
    section = README[README.index("## Using your own data") : README.index("## Results")]
    setup = re.search(r"`(wavemeter simulate -o scan\.csv[^`]*)`", section).group(1)
    steps, current = [], None
    for line in section.splitlines():
        if line.startswith("    $ "):
            current = (line[6:], [])
            steps.append(current)
        elif current is not None and line.startswith("    ") and line.strip():
            current[1].append(line[4:])
        else:
            current = None
    return " ".join(setup.split()), steps


def run(command: str, capsys) -> list[str]:
    """Run a README command (``wavemeter ...`` or ``head -N FILE``); its printed lines."""
    words = shlex.split(command)
    if words[0] == "head":
        count = int(words[1].lstrip("-"))
        return Path(words[2]).read_text().splitlines()[:count]
    assert words[0] == "wavemeter"
    code = main(words[1:])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    return (printed.out + printed.err).splitlines()


def test_the_walk_through_prints_what_the_readme_shows(tmp_path, monkeypatch, capsys):
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
                assert line in printed, f"{command}: README line not printed: {line!r}"


def test_the_python_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = re.search(r"```python\n(.*?)```", README, re.S).group(1)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102 - the README's own code
    assert namespace["cal"].fsr_hz_ == pytest.approx(namespace["dev"].true_fsr_hz, rel=1e-4)
    assert (tmp_path / "chip.wmcal.json").is_file()


def test_the_noise_example_recovers_the_laser_it_simulates(tmp_path, monkeypatch):
    """The frequency-noise example, run after the first example (its ``dev`` and ``cal``),
    recovers the simulated laser's linewidth and drift within 3 of their stated standard
    deviations."""
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```python\n(.*?)```", README, re.S)
    noise = next(block for block in blocks if "frequency_noise(" in block)
    namespace: dict = {}
    for code in (blocks[0], noise):
        exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102 - the README's code
    result = namespace["result"]
    assert not result.linewidth_is_upper_limit
    assert abs(result.lorentzian_linewidth_hz - 500e6) < 3 * result.lorentzian_linewidth_std_hz
    assert abs(result.drift_hz_per_s - 1e9) < 3 * result.drift_std_hz_per_s


def test_the_wide_band_example_chooses_the_orders_the_readme_states(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    section = README[README.index("### Wide band") : README.index("## Using your own data")]
    commands = [
        " ".join(match.split())
        for match in re.findall(r"^    (wavemeter (?:[^\n]*\\\n)*[^\n]*)", section, re.M)
    ]
    simulate, calibrate = (command.replace("\\", "") for command in commands[:2])
    run(simulate, capsys)
    run(calibrate.split("#")[0], capsys)
    orders = re.search(r"chose phase order (\d) and map order (\d)", " ".join(section.split()))
    info = "\n".join(run("wavemeter info band.wmcal.json", capsys))
    assert f"phase_order      {orders.group(1)}" in info
    assert f"map_order        {orders.group(2)}" in info
    stated = re.search(r"fell from (\S+) MHz .*? to (\S+) MHz", " ".join(section.split()))
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


def test_the_cascade_example_prints_what_the_readme_states(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    section = README[README.index("### Cascade") : README.index("## Using your own data")]
    commands = [
        " ".join(match.replace("\\", "").split())
        for match in re.findall(r"^    (wavemeter (?:[^\n]*\\\n)*[^\n]*)", section, re.M)
    ]
    design, simulate, calibrate = commands[:3]
    printed = run(design, capsys)
    stated = re.search(r"three stages,\s+(\S+) THz / (\S+) GHz / 50 GHz", section)
    fsrs_ghz = [line.split()[1] for line in printed[1:4]]
    assert [f"{float(fsrs_ghz[0]) / 1e3:.3g}", f"{float(fsrs_ghz[1]):.3g}"] == list(stated.groups())
    assert fsrs_ghz[2] == "50" and printed[4].startswith("band:")
    run(simulate, capsys)
    run(calibrate.split("#")[0], capsys)
    info = run("wavemeter info cband.wmcal.json", capsys)
    for line in re.findall(r"^    (hand-over [^\n]*)", section, re.M):
        assert line in info
    evaluated = run("wavemeter evaluate cband.wmcal.json cband-test.csv", capsys)
    row = next(line for line in evaluated if line.startswith("cascade "))
    ratio = re.search(r"(\S+) MHz RMS,\s+(\S+)x the Cramer-Rao bound", section)
    assert f"{float(row.split()[1]):.3g}" == ratio.group(1) and row.split()[-1] == ratio.group(2)
    assert any("0 of 5000 readings off" in line for line in evaluated)
