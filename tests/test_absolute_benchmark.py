"""Smoke test of benchmarks/absolute.py in its quick mode (one seed, 3 ports, each laser):
the script runs, prints its tables, and each target's PASS/FAIL agrees with the number it
prints beside it."""

from __future__ import annotations

import importlib
import re
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.slow
def test_quick_run_prints_consistent_targets():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        absolute = importlib.import_module("absolute")
        output = StringIO()
        with redirect_stdout(output):
            code = absolute.main(["--quick"])
    text = output.getvalue()
    for heading in ("## Budget terms", "## Absolute accuracy beside the anchors", "## Targets"):
        assert heading in text
    rows = [line for line in text.splitlines() if line.endswith(("| PASS |", "| FAIL |"))]
    assert len(rows) == 3 * 9  # three lasers, nine targets each
    for row in rows:
        target, measured, status = (cell.strip() for cell in row.strip("|").split("|"))
        ratio = re.search(r"= ([0-9.]+)", measured)
        if "<= 1.2x stated budget" in target and ratio:
            assert (float(ratio.group(1)) <= 1.2) == (status == "PASS")
        if "z std in 0.9-1.1" in target:
            assert (0.9 <= float(measured) <= 1.1) == (status == "PASS")
    assert code == (0 if all(row.endswith("| PASS |") for row in rows) else 1)
