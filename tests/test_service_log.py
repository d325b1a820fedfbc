"""Parquet logs of `wavemeter serve --log`: SIGTERM writes every published reading,
``kill -9`` leaves readable files short of at most the last second, a restart starts new
files and joins what a killed run left."""

from __future__ import annotations

import re
import signal
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from wavemeter.service import read_log  # noqa: E402  (after the skip of _service)

from ._service import EPHEMERAL, Serve, serving

#: each test starts real `wavemeter serve` processes (seconds each): not the fast tier
pytestmark = pytest.mark.slow


def _consecutive(table) -> dict[int, int]:
    """Readings per channel, checking each channel's sequences are 0, 1, 2, ..."""
    counts = {}
    channel = table.column("channel").to_numpy()
    sequence = table.column("sequence").to_numpy()
    for index in np.unique(channel):
        mine = sequence[channel == index]
        assert (mine == np.arange(len(mine))).all(), index
        counts[int(index)] = len(mine)
    return counts


def test_sigterm_writes_every_published_reading(tmp_path):
    args = ["--simulate", "--channels", "2", "--log", str(tmp_path), "--log-powers", *EPHEMERAL]
    with serving(args) as service:
        time.sleep(2.5)
        assert service.stop(signal.SIGTERM) == 0
    published = int(re.search(r"published (\d+) readings", service.stderr)[1])
    table = read_log(tmp_path)
    assert table.num_rows == published > 1000
    counts = _consecutive(table)
    assert sorted(counts) == [0, 1] and sum(counts.values()) == published
    for name in ("time_ns", "frequency_hz", "frequency_std_hz", "flags", "true_frequency_hz"):
        assert name in table.column_names
    assert {"P1_w", "P2_w", "P3_w"} <= set(table.column_names)
    # a closed segment per channel, no part left over
    files = sorted(p.name for p in tmp_path.rglob("*.parquet"))
    assert len(files) == 2 and not any(".part" in name for name in files)
    assert read_log(tmp_path, channel=1).num_rows == counts[1]


def test_kill_9_leaves_readable_files_missing_at_most_a_second(tmp_path):
    service = Serve(["--simulate", "--log", str(tmp_path), *EPHEMERAL])
    try:
        service.wait_ready()
        time.sleep(3.0)
        killed_ns = time.time_ns()
        service.stop(signal.SIGKILL)
    finally:
        service.stop()
    files = list(tmp_path.rglob("*.parquet"))
    assert files
    tables = [pq.read_table(path) for path in files]  # every file reads
    assert all(table.num_rows for table in tables)
    table = read_log(tmp_path)
    _consecutive(table)
    last_s = (killed_ns - table.column("source_time_ns").to_numpy().max()) * 1e-9
    assert 0 <= last_s <= 1.0
    # a restart joins the killed run's parts and writes a segment of its own
    with serving(["--simulate", "--log", str(tmp_path), *EPHEMERAL]):
        time.sleep(1.5)
    names = sorted(p.name for p in tmp_path.rglob("*.parquet"))
    assert len(names) == 2 and not any(".part" in name for name in names)
    runs = read_log(tmp_path)
    assert runs.num_rows > table.num_rows
    # two runs, each numbered from 0
    assert int((runs.column("sequence").to_numpy() == 0).sum()) == 2


def test_logs_rotate_by_time_and_read_back_whole(tmp_path):
    args = ["--simulate", "--log", str(tmp_path), "--log-rotate", "1s", *EPHEMERAL]
    with serving(args) as service:
        time.sleep(3.0)
        assert service.stop(signal.SIGTERM) == 0
    published = int(re.search(r"published (\d+) readings", service.stderr)[1])
    segments = sorted((tmp_path / "ch0").glob("*.parquet"))
    assert len(segments) >= 2 and not any(".part" in p.name for p in segments)
    table = read_log(tmp_path)
    assert _consecutive(table) == {0: published}
