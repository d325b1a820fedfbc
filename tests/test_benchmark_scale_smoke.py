"""Smoke test of benchmarks/scale.py's parts on small sizes (the numbers are the benchmark's)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from .helpers import BENCHMARKS, table_rows

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def scale():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        yield importlib.import_module("scale")


def test_moment_fit_row_agrees_with_todays_search(scale):
    row = scale.fit_row(2_000, runs=1)
    assert len(row) == len(scale.FIT_HEADERS)
    delay_rel, map_rel = float(row[5]), float(row[6])
    assert delay_rel <= scale.DELAY_RTOL and map_rel <= scale.MAP_RTOL
    assert row[-1] == "PASS"
    assert float(row[7]) > 0  # the chunked child's peak memory (MiB)


def test_predict_row_times_every_path_against_arctan2(scale):
    frequency, powers = scale.sweep(4_000)
    cals = {
        retrieval: scale.wm.Calibrator(fsr_hz=scale.FSR_HZ, retrieval=retrieval).fit(
            powers, frequency
        )
        for retrieval in ("pinv", "ml")
    }
    row, throughput = scale.predict_row(2_000, powers, cals, runs=1)
    assert len(row) == len(scale.PREDICT_HEADERS)
    assert len(throughput) == len(scale.THROUGHPUT_HEADERS)
    assert all(float(cell.split()[0]) > 0 for cell in row[1:])
    # each path's throughput is the arctangent's over its time ratio (the same runs)
    arctan_rate = float(throughput[1])
    for ratio, rate in zip(row[2:], throughput[2:], strict=True):
        assert float(rate) == pytest.approx(arctan_rate / float(ratio.split()[0]), rel=0.02)
    # the switch between the paths is undone: the next predict takes the default path again
    assert scale.numba_kernel.kernel_backend() in scale.kernels.BACKENDS
    assert np.isfinite(cals["pinv"].predict(powers)).all()


def test_measure_table_has_both_formats_and_the_memory_target(scale):
    pytest.importorskip("pyarrow")
    text = scale.measure_table((2_000, 4_000))
    tables = [table_rows(part) for part in text.split("\n\n")]
    assert [row[0] for row in tables[0][2:]] == ["CSV", "CSV", "Parquet", "Parquet"]
    assert [row[0] for row in tables[1][2:]] == ["CSV", "Parquet"]
    assert all(row[-1] in ("PASS", "FAIL") for row in tables[1][2:])
