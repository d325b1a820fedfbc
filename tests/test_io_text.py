"""Text tables read a block of ``_BLOCK_BYTES`` at a time (``wavemeter.io.text``): line ends
are counted for progress, right also where a block ends between the two bytes of a CRLF or
inside a last line without a newline; blocks that cut lines anywhere give the whole file's
rows, in order, at every chunk size, with pyarrow and with the line parser.

The blocks are made small by setting the module's ``_BLOCK_BYTES``, hence the file named
after the module.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.io import ColumnRequest, iter_readings, read_table
from wavemeter.io import text as text_module

from .helpers import NOISE_W, POWER_W, random_test_frequencies, text_with_comments_and_blank_lines

ROWS = 60
#: rows whose port 2 reading is missing (NaN)
MISSING_ROWS = (0, 6, 7, 33, 59)
CHUNK_SIZES = (1, 7, 10_000)


@pytest.fixture(scope="module")
def chip() -> dict:
    """Readings of a simulated 3-port chip with a time column, some missing."""
    device = wm.Interferometer.table1(3, seed=3)
    rng = np.random.default_rng(3)
    powers = device.powers(random_test_frequencies(device, ROWS, rng), POWER_W, NOISE_W, rng=rng)
    powers[list(MISSING_ROWS), 1] = np.nan
    return {"powers": powers, "time_s": np.arange(ROWS) * 0.25}


@pytest.mark.slow
@pytest.mark.parametrize("block_bytes", [1, 2, 3, 7, 1 << 20])
def test_rows_are_counted_across_block_edges(tmp_path, monkeypatch, block_bytes):
    """Line ends counted a block at a time, also where a block ends between the two bytes
    of a CRLF or inside a last line without a newline: the rows a read finds, and one more
    for each blank line after the header."""
    monkeypatch.setattr("wavemeter.io.text._BLOCK_BYTES", block_bytes)
    rng = np.random.default_rng(block_bytes)
    for newline in ("\n", "\r\n", "\r"):
        for _ in range(20):
            lines = []
            for k in range(int(rng.integers(1, 12))):
                lines += [""] * int(rng.integers(0, 2)) + [f"{k + 1},2,3"]
            lines += [""] * int(rng.integers(0, 3))
            ended = rng.random() < 0.7
            path = tmp_path / "r.csv"
            text = newline.join(["p1,p2,p3", *lines]) + (newline if ended else "")
            path.write_bytes(text.encode())
            stream = iter_readings(path, allow_invalid=True)
            rows = sum(chunk.n_rows for chunk in stream)
            blank = lines.count("") - (not ended and lines[-1] == "")
            assert rows == len(lines) - lines.count("")
            assert stream.progress_total == (rows + blank, "rows"), repr(text)


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"])
@pytest.mark.parametrize("parser", ["arrow", "lines"])
def test_csv_blocks_cut_mid_line_give_the_same_rows(chip, tmp_path, monkeypatch, newline, parser):
    """Blocks of 37 bytes cut lines (and CRLF pairs) anywhere; the rows are the whole
    file's, in order, at every chunk size, with pyarrow and with the line parser."""
    text, _ = text_with_comments_and_blank_lines(chip, newline)
    data = tmp_path / "r.csv"
    data.write_bytes(text.encode())
    monkeypatch.setattr(text_module, "_BLOCK_BYTES", 37)
    if parser == "lines":
        monkeypatch.setitem(sys.modules, "pyarrow", None)  # as where it is not installed
    whole = read_table(data, ColumnRequest(keep=("time_s",)), need_x=False, allow_invalid=True)
    for chunk_rows in CHUNK_SIZES:
        stream = iter_readings(
            data, ColumnRequest(keep=("time_s",)), chunk_rows=chunk_rows, allow_invalid=True
        )
        chunks = list(stream)
        assert all(chunk.n_rows <= chunk_rows for chunk in chunks)
        powers = np.concatenate([chunk.powers_w for chunk in chunks])
        np.testing.assert_array_equal(powers, whole.powers_w)
        kept = np.concatenate([chunk.kept["time_s"] for chunk in chunks])
        np.testing.assert_array_equal(kept, chip["time_s"])
        # rows read; the total counted from line ends (each blank line counts)
        blank = text.count(newline * 2)
        assert stream.progress == ROWS and stream.progress_total == (ROWS + blank, "rows")
