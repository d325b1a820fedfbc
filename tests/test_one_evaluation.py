"""The report and ``wavemeter evaluate`` give the same figures for the same files.

Issue 29, "one evaluation": for every method, the report's error table (RMS, max, p95, p99,
RMS over the bound, the error modulo the FSR, the gross-error share, the bound itself and
the number of readings) shows evaluate's numbers, rounded to the digits the report prints
and to nothing else. Both commands run on the files ``wavemeter simulate`` wrote, as a user
runs them.
"""

from __future__ import annotations

import json
import shlex
from html.parser import HTMLParser

import pytest

from wavemeter.cli import main

#: per method: the files to simulate (name -> options; the test readings are t-test.csv),
#: the calibration's options (its sweeps first), and whether the report compares it with
#: another method fitted on its first sweep (evaluate's --sweep does the same)
CASES = {
    "learned": ({"t": "--seed 1 --samples 1001 --test 2000"}, "t.csv --fsr 50GHz", True),
    "conventional": (
        {"t": "--seed 1 --samples 1001 --test 2000"},
        "t.csv --fsr 50GHz --method conventional",
        True,
    ),
    "per-FSR set": (
        {"t": "--seed 4 --span-fsr 3 --samples 3000 --test 2000"},
        "t.csv --per-fsr",
        True,
    ),
    "thermal": (
        {
            "s292": "--platform sin --temperature-k 292 --samples 1001",
            "s295": "--platform sin --temperature-k 295 --samples 1001",
            "t": "--platform sin --ramp-k 292:295 --samples 1001 --test 2000",
        },
        "s292.csv s295.csv --method thermal",
        True,
    ),
    "wide band": (
        {"t": "--seed 2 --spectral sin --dispersion 1e-26 --span-fsr 8 --samples 3200 --test 2000"},
        "t.csv --method wideband",
        True,
    ),
    "cascade": (
        {"t": "--seed 1 --cascade 5THz,500GHz,50GHz --spectral sin --samples 12000 --test 2000"},
        "t.csv --method cascade --fsr 5THz,500GHz,50GHz",
        False,
    ),
}
#: the report's column -> the field of evaluate's JSON it shows, and its scale
COLUMNS = {
    "RMS (MHz)": ("rms_abs_hz", 1e-6),
    "max (MHz)": ("max_abs_hz", 1e-6),
    "p95 (MHz)": ("p95_abs_hz", 1e-6),
    "p99 (MHz)": ("p99_abs_hz", 1e-6),
    "RMS / CRLB": ("rms_abs_over_crlb", 1.0),
    "RMS mod FSR (MHz)": ("rms_mod_fsr_hz", 1e-6),
    "RMS mod FSR / CRLB": ("rms_mod_fsr_over_crlb", 1.0),
    "off by half an FSR or more": ("gross_error_fraction", 100.0),
}


class _Tables(HTMLParser):
    """The text of every table cell and the heading before each table."""

    def __init__(self):
        super().__init__()
        self.tables: list[tuple[str, list[list[str]]]] = []
        self._heading = ""
        self._in_heading = False
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "h2":
            self._in_heading, self._heading = True, ""
        elif tag == "table":
            self.tables.append((self._heading, []))
        elif tag == "tr" and self.tables:
            self.tables[-1][1].append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "h2":
            self._in_heading = False
        elif tag in ("td", "th") and self._cell is not None:
            self.tables[-1][1][-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data):
        if self._in_heading:
            self._heading += data
        if self._cell is not None:
            self._cell.append(data)


def _run(capsys, command: str) -> str:
    code = main(shlex.split(command))
    out, err = capsys.readouterr()
    assert code == 0, f"wavemeter {command}: exit {code}\n{err}"
    return out


def _agrees_to_the_digit(shown: str, value: float) -> bool:
    """``shown`` is ``value`` rounded to the digits ``shown`` has (``2440``: tens)."""
    text = shown.replace("%", "").strip()
    number = float(text)
    if "." in text:
        unit = 10.0 ** -len(text.split(".")[1])
    else:
        digits = text.lstrip("-")
        unit = 10.0 ** (len(digits) - len(digits.rstrip("0"))) if digits != "0" else 1.0
    return abs(number - value) <= 0.5 * unit * (1 + 1e-9) + 1e-12 * abs(value)


@pytest.mark.slow
@pytest.mark.parametrize(
    "case",
    [pytest.param(name, marks=() if name == "learned" else pytest.mark.slow) for name in CASES],
)
def test_the_report_shows_the_figures_evaluate_prints(case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    simulations, options, compared_on_sweep = CASES[case]
    for name, simulate in simulations.items():
        _run(capsys, f"simulate -o {name}.csv {simulate}")
    calibration, test, sweep = "c.wmcal.json", "t-test.csv", options.split()[0]
    _run(capsys, f"calibrate {options} -o {calibration} --quiet")
    other = f"--sweep {sweep}" if compared_on_sweep else ""
    evaluated = json.loads(_run(capsys, f"evaluate {calibration} {test} {other} --json"))
    _run(capsys, f"report {calibration} {sweep} {test} -o r.html --quiet")
    parser = _Tables()
    parser.feed((tmp_path / "r.html").read_text(encoding="utf-8"))
    heading, rows = next(
        (heading, rows) for heading, rows in parser.tables if heading.startswith("Frequency error")
    )
    assert f"({evaluated['samples']} readings)" in heading
    header, *body = rows
    by_label = {row[0]: row for row in body}
    crlb = by_label.pop("CRLB", None)
    if crlb is not None:
        assert _agrees_to_the_digit(crlb[header.index("RMS (MHz)")], evaluated["crlb_rms_hz"] / 1e6)
    assert by_label, "the report's error table has no method row"
    for label, row in by_label.items():
        # evaluate names a method fitted for comparison with the file it was fitted on
        matches = [key for key in evaluated["methods"] if key.split(" (")[0] == label]
        assert len(matches) == 1, (label, list(evaluated["methods"]))
        figures = evaluated["methods"][matches[0]]
        compared = 0
        for column, shown in zip(header[1:], row[1:], strict=True):
            if column not in COLUMNS or not shown:
                continue
            field, scale = COLUMNS[column]
            assert figures[field] is not None, (label, column)
            value = figures[field] * scale
            assert _agrees_to_the_digit(shown, value), (label, column, shown, value)
            compared += 1
        assert compared >= 6, (label, header)


@pytest.mark.slow
def test_measure_evaluate_and_the_report_count_the_same_flags(tmp_path, capsys, monkeypatch):
    """A calibration over half an FSR reads a test over the whole FSR: about half the
    readings are flagged OUTSIDE_SPAN, and the three commands count the same ones."""
    monkeypatch.chdir(tmp_path)
    _run(capsys, "simulate -o half.csv --seed 1 --span-fsr 0.5 --samples 1001 --quiet")
    _run(capsys, "simulate -o whole.csv --seed 1 --samples 1001 --test 3000 --quiet")
    _run(capsys, "calibrate half.csv -o c.wmcal.json --quiet")
    measured = main(shlex.split("measure c.wmcal.json whole-test.csv -o out.csv"))
    assert measured == 0
    counted = capsys.readouterr()
    line = next(
        text for text in (counted.out + counted.err).splitlines() if text.startswith("flagged ")
    )
    assert "OUTSIDE_SPAN" in line
    flagged = int(line.split()[1])
    assert 0.3 * 3000 < flagged < 0.7 * 3000
    evaluated = _run(capsys, "evaluate c.wmcal.json whole-test.csv")
    assert f"learned: {line}" in evaluated.splitlines()
    _run(capsys, "report c.wmcal.json half.csv whole-test.csv -o r.html --quiet")
    assert f"learned: {line}" in (tmp_path / "r.html").read_text(encoding="utf-8")
