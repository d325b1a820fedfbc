"""Smoke test of the service benchmark (benchmarks/serve.py) in its short mode: every table
prints with its rows, and the numbers are real measurements (positive, finite)."""

from __future__ import annotations

import contextlib
import importlib
import io
import re

import pytest

from .helpers import BENCHMARKS

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")


@pytest.mark.slow
def test_serve_benchmark_quick_run_prints_its_tables():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        serve = importlib.import_module("serve")
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert serve.main(["--quick"]) == 0
    text = out.getvalue()
    for case in ("wavemeter stream (stdout)", "serve, 1 subscriber", "serve, 3 subscribers"):
        row = next(line for line in text.splitlines() if line.startswith(f"| {case} |"))
        median, p99 = (float(cell) for cell in row.split("|")[2:4])
        assert 0 < median <= p99 < 10_000  # ms
    assert re.search(r"\| wavemeter serve \(1 subscriber\) \| \d+\.\d{3} \|", text)
    assert re.search(r"\| 2,000 \| whole \| 1000 sent, gaps 0, dropped 0, logged 1000", text)
    assert "highest sustained: 2,000 readings/s" in text
