"""The service reads lines by the rules of `wavemeter stream`: a block of lines gives what
the line-by-line reader gives, and the published numbers are those `stream` writes."""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import wavemeter as wm
from wavemeter.io import ColumnRequest
from wavemeter.jobs import LineReader, read_header, stream_lines

pytest.importorskip("zmq", reason="the serve extra (pyzmq) is not installed")

from wavemeter.service.channels import Channel  # noqa: E402
from wavemeter.service.lines import LineParser  # noqa: E402
from wavemeter.service.readout import CalibrationReader  # noqa: E402
from wavemeter.service.simulated import NOISE_W, POWER_W, simulated_meter  # noqa: E402

HEADER = "P1_mW,P2_mW,note,P3_mW"
CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", " 0.5 ", "abc", '"0.25"', '"a,b"', "1_0", "-0.0", "nan", "\x00"]),
)
LINES = st.lists(CELLS, min_size=1, max_size=6).map(",".join)


def _reader() -> LineReader:
    header = read_header(iter([(1, HEADER)]), Path("<x>"), ColumnRequest(), False)
    return LineReader(header)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.lists(LINES, min_size=1, max_size=8))
def test_a_block_of_lines_reads_as_each_line_does(lines):
    reader = _reader()
    data, reasons = reader.block(lines)
    for row, line in enumerate(lines):
        values, reason = reader.values(line)
        assert reasons[row] == reason
        for name in ("P1_mW", "P2_mW", "P3_mW"):
            expected = np.nan if values is None else values[name]
            np.testing.assert_equal(data[name][row], expected)


def test_the_service_publishes_what_stream_writes():
    device, calibration = simulated_meter(7)
    rng = np.random.default_rng(11)
    truth = device.center_hz + rng.uniform(-20e9, 20e9, 60)
    powers_mw = device.powers(truth, power_w=POWER_W, noise_w=NOISE_W, rng=rng) * 1e3
    lines = [",".join(repr(float(p)) for p in row) for row in powers_mw]
    lines[5] = "0.1,abc,0.2"
    lines[9] = "nan,0.2,0.3"
    lines[13] = "0,0,0"
    out = io.StringIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        stream_lines(calibration, ["P1_mW,P2_mW,P3_mW", *lines], out)
    written = np.genfromtxt(io.StringIO(out.getvalue()), delimiter=",", names=True)
    parser = LineParser("<lines>")
    parser.start(["P1_mW,P2_mW,P3_mW"], calibration)
    reader = CalibrationReader(calibration)
    channel = Channel(0)
    # in one block (readout), a line at a time (calibration.stream), and in blocks of 3 and
    # 5 lines (converted row by row up to 4, some with an invalid line among them)
    sizes = (len(lines), 1, 3, 5)
    for blocks in ([lines[k : k + size] for k in range(0, len(lines), size)] for size in sizes):
        channel.next_sequence = 0
        batches = [channel.process(parser.rows(block, 0), reader, "run") for block in blocks]
        columns = {
            name: np.concatenate([b.columns[name] for b in batches])
            for name in ("sequence", "frequency_hz", "frequency_std_hz", "flags")
        }
        assert (columns["sequence"] == np.arange(len(lines))).all()
        assert (columns["flags"] == written["flags"]).all()
        for name in ("frequency_hz", "frequency_std_hz"):
            np.testing.assert_allclose(columns[name], written[name], rtol=1e-13, equal_nan=True)
    assert (written["flags"][[5, 9, 13]].astype(int) & wm.ReadingFlag.INVALID).all()


def test_a_lone_line_reads_as_in_a_block_on_a_switch_schedule():
    """Lines one at a time (the lone-line path) give the block's channels, powers, invalid
    rows and counts, with the switch schedule going on across the invalid ones."""
    _, calibration = simulated_meter(7)
    lines = ["0.3,0.2,0.25", "0.1,abc,0.2", "# a comment", "0.2,0.2,0.2", "nan,1,1", "1,2,3"]
    lines += ["9.91e37,1,1", "1e20,1,1", "-1,0.5,0.4", "0,0,0", "inf,1,1", "1e-300,0,0"]
    rng = np.random.default_rng(5)
    lines += [",".join(repr(float(v)) for v in row) for row in rng.lognormal(-1, 2, (40, 3))]
    for header in ("P1_mW,P2_mW,P3_mW", "P1_W,P2_W,P3_W", "P1_nW,P2_uW,P3_V", "P1,P2,P3"):
        alone, together = (LineParser(name, channels=3) for name in ("alone", "together"))
        for parser in (alone, together):
            parser.start([header], calibration)
        blocks = [block for line in lines if (block := alone.rows([line], 7)) is not None]
        block = together.rows(lines, 7)
        assert len(blocks) == len(lines) - 1 == len(block)
        for name in ("channel", "invalid", "powers_w"):
            found = np.concatenate([getattr(b, name) for b in blocks])
            np.testing.assert_array_equal(found, getattr(block, name), err_msg=header)
        assert alone.counts == together.counts
        np.testing.assert_array_equal(block.channel[:5], [0, 1, 2, 0, 1])
        # text, NaN, a power-meter code, 0 W and inf are no reading in any unit
        assert {1, 3, 5, 8, 9} <= set(np.flatnonzero(block.invalid)) and not block.invalid[6]
