"""Smoke test of ``benchmarks/lock.py`` in its quick configuration (one seed of 12 s, no run
through ``serve``): the bound's table, a row per scenario, and every target met on this
seed, the fault counts among them, and the output's step at a re-anchor below the correction
(the full run is ``make lock-bench``)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"

pytestmark = pytest.mark.slow


def _rows(text: str, heading: str) -> list[list[str]]:
    part = text[text.index(heading) :].split("\n\n", 2)[1]
    return [[cell.strip() for cell in line.strip("|").split("|")] for line in part.splitlines()]


def test_the_quick_lock_benchmark_prints_its_tables_and_meets_its_targets(capsys):
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        lock = importlib.import_module("lock")
        lock.main(["--quick", "--no-service"])
    text = capsys.readouterr().out
    bound = {row[0]: row[1] for row in _rows(text, "## The bound")[2:]}
    bound_mhz = float(bound["**bound: best PI RMS error against the truth**"].strip("* MHz"))
    # the loop alone cannot beat the meter's white noise averaged over its bandwidth, nor can
    # the bound be below the meter's static error at the setpoint
    static_mhz = float(bound["meter static error at the setpoint"].split()[0])
    assert static_mhz < bound_mhz < 5.0
    table = _rows(text, "## Side by side")
    names = [row[0] for row in table[2:]]
    assert names == [
        "free-running",
        "locked",
        "locked, 1 GHz away",
        "chip ramp, no reference",
        "chip ramp, reference",
    ]
    rms = {row[0]: float(row[1]) for row in table[2:]}
    assert rms["locked"] <= 1.3 * bound_mhz
    assert rms["chip ramp, no reference"] > 100 * rms["chip ramp, reference"]
    # locks run through the re-anchors: the output's step at one is a fraction of the
    # correction (the loop's gain per reading on the moved reading, and its noise)
    step = re.search(r"Re-anchors per run: (\d+) accepted, (\d+) refused; .* is (\S+) of its", text)
    assert int(step[1]) > 100 and int(step[2]) == 0 and float(step[3]) < 1.0
    targets = _rows(text, "## Targets")[2:]
    assert len(targets) == 8
    assert [row[1] for row in targets] == ["PASS"] * 8, targets
