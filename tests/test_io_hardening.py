"""Hostile and careless inputs (issue 16): every reader refuses cleanly, fast, and safely.

One test (or a few) per defect: HDF5 data outside the file, declared sizes beyond the
limit, damaged archives, NPZ members read only when used, pipes and devices read once and
bounded, rows with the wrong number of fields, truncated last lines, implausible dBm,
spreadsheet formulas in CSV output, NPZ member names, output extensions.
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
import threading
import time
import warnings
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy import io as scipy_io

from wavemeter.exceptions import FileFormatError, InputError, WavemeterError
from wavemeter.io import MAX_BYTES, MAX_DBM, read_table, table_format, write_table

ROWS = 20
FREQUENCY_HZ = 193.4e12 + np.arange(ROWS) * 1e9
POWERS_W = np.random.default_rng(5).uniform(1e-4, 1e-3, (ROWS, 3))


def _hdf5_sweep(path: Path, **frequency_options) -> Path:
    with h5py.File(path, "w") as handle:
        handle.create_dataset("frequency_hz", **frequency_options)
        handle.create_dataset("P_W", data=POWERS_W)
    return path


def _csv(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _sweep_text(rows: int = ROWS) -> str:
    lines = ["frequency_hz,p1_w,p2_w,p3_w"]
    lines += [
        ",".join(map(repr, (float(FREQUENCY_HZ[k]), *POWERS_W[k].tolist()))) for k in range(rows)
    ]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- HDF5
def test_hdf5_dataset_stored_in_an_external_raw_file_is_refused(tmp_path):
    secret = tmp_path / "secret.bin"
    secret.write_bytes(FREQUENCY_HZ.tobytes())
    path = _hdf5_sweep(
        tmp_path / "s.h5", shape=(ROWS,), dtype="f8", external=[(str(secret), 0, 8 * ROWS)]
    )
    with pytest.raises(FileFormatError, match=r"'frequency_hz' keeps its values in 1 external"):
        read_table(path)


def test_hdf5_virtual_dataset_is_refused(tmp_path):
    with h5py.File(tmp_path / "other.h5", "w") as handle:
        handle.create_dataset("f", data=FREQUENCY_HZ)
    layout = h5py.VirtualLayout(shape=(ROWS,), dtype="f8")
    layout[:] = h5py.VirtualSource(str(tmp_path / "other.h5"), "f", shape=(ROWS,))
    path = tmp_path / "s.h5"
    with h5py.File(path, "w") as handle:
        handle.create_virtual_dataset("frequency_hz", layout)
        handle.create_dataset("P_W", data=POWERS_W)
    with pytest.raises(FileFormatError, match=r"'frequency_hz' is a virtual dataset"):
        read_table(path)


def test_hdf5_soft_and_external_links_are_not_followed(tmp_path):
    with h5py.File(tmp_path / "other.h5", "w") as handle:
        handle.create_dataset("frequency_hz", data=FREQUENCY_HZ)
    path = tmp_path / "s.h5"
    with h5py.File(path, "w") as handle:
        handle["frequency_hz"] = h5py.ExternalLink(str(tmp_path / "other.h5"), "frequency_hz")
        for port in range(3):
            handle.create_dataset(f"p{port + 1}", data=POWERS_W[:, port])
        handle["p4"] = h5py.SoftLink("/p1")
    with pytest.raises(InputError, match="no frequency or wavelength column"):
        read_table(path)
    assert read_table(path, need_x=False).port_names == ("p1", "p2", "p3")


def test_hdf5_declaring_32_gb_in_a_small_file_fails_fast_before_reading(tmp_path):
    path = _hdf5_sweep(tmp_path / "s.h5", shape=(4 * 10**9,), dtype="f8")
    assert path.stat().st_size < 16_000
    start = time.perf_counter()
    with pytest.raises(
        FileFormatError,
        match=r"'frequency_hz' of shape \(4000000000,\) would "
        r"take 32 GB, more than the 2.15 GB size limit",
    ) as err:
        read_table(path)
    assert time.perf_counter() - start < 1.0
    assert err.value.parameter == "max_bytes" and MAX_BYTES == 2**31


def test_size_limit_is_an_argument(tmp_path):
    path = _hdf5_sweep(tmp_path / "s.h5", data=FREQUENCY_HZ)
    assert read_table(path).n_rows == ROWS
    with pytest.raises(FileFormatError, match="would take 160 bytes, more than the 100 bytes"):
        read_table(path, max_bytes=100)


def test_hdf5_contiguous_data_past_the_end_of_the_file_is_truncation(tmp_path):
    path = _hdf5_sweep(tmp_path / "s.h5", data=np.repeat(FREQUENCY_HZ, 200)[: ROWS * 200])
    with h5py.File(path, "r+") as handle:  # a 4000-sample axis needs 4000-sample ports
        del handle["P_W"]
        handle.create_dataset("P_W", data=np.tile(POWERS_W, (200, 1)), compression="gzip")
    with h5py.File(path, "r") as handle:
        offset = handle["frequency_hz"].id.get_offset()
    truncated = tmp_path / "cut.h5"
    truncated.write_bytes(path.read_bytes()[: offset + 100])
    with pytest.raises(FileFormatError, match=r"cut.h5: ") as err:
        read_table(truncated)
    assert "Traceback" not in str(err.value)


def test_hdf5_names_that_are_not_utf8_are_read(tmp_path):
    """h5py hands such paths over as bytes: ``startswith first arg must be bytes``."""
    path = tmp_path / "s.h5"
    with h5py.File(path, "w") as handle:
        handle.create_dataset("frequency_hz", data=FREQUENCY_HZ)
        group = handle.create_group(b"caf\xe9")
        for port in range(3):
            group.create_dataset(f"p{port + 1}_w", data=POWERS_W[:, port])
    table = read_table(path)
    assert table.port_names == ("caf\ufffd/p1_w", "caf\ufffd/p2_w", "caf\ufffd/p3_w")
    np.testing.assert_array_equal(table.powers_w, POWERS_W)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["hdf5", "mat73"])
def test_one_damaged_byte_in_hdf5_gives_a_file_format_error(tmp_path, kind):
    path = tmp_path / ("s.h5" if kind == "hdf5" else "s.mat")
    with h5py.File(path, "w", userblock_size=512 if kind == "mat73" else 0) as handle:
        handle.create_dataset("frequency_hz", data=FREQUENCY_HZ)
        handle.create_dataset("P_W", data=POWERS_W.T)
    original = path.read_bytes()
    outcomes = set()
    for position in range(0, len(original), 29):
        damaged = bytearray(original)
        damaged[position] ^= 0xFF
        path.write_bytes(bytes(damaged))
        try:
            read_table(path, allow_invalid=True)
            outcomes.add("read")
        except WavemeterError as exc:
            assert str(exc).startswith(f"{path}: "), exc
            outcomes.add("error")
    assert "error" in outcomes


# ---------------------------------------------------------------------------- MAT v5
def _mat_v5_sweep(compressed: bool) -> bytes:
    buffer = io.BytesIO()
    sweep = {"frequency_hz": FREQUENCY_HZ, "P_W": POWERS_W}
    scipy_io.savemat(buffer, {"sweep": sweep, "note": "text"}, do_compression=compressed)
    return buffer.getvalue()


def test_mat_v5_array_flagged_complex_without_imaginary_part_is_no_crash(tmp_path):
    """scipy.io.loadmat crashes the interpreter (SIGSEGV) on this file."""
    content = bytearray(_mat_v5_sweep(compressed=False))
    flags = [k for k in range(len(content) - 12) if content[k : k + 8] == b"\x06\0\0\0\x08\0\0\0"]
    content[flags[2] + 8 : flags[2] + 12] = (0x6B06).to_bytes(4, "little")  # field P_W
    path = tmp_path / "s.mat"
    path.write_bytes(bytes(content))
    with pytest.raises(InputError, match="no port columns .* columns: 'sweep/frequency_hz'"):
        read_table(path)


@pytest.mark.slow
@pytest.mark.parametrize("compressed", [False, True])
def test_one_damaged_byte_in_mat_v5_gives_a_file_format_error(tmp_path, compressed):
    original = _mat_v5_sweep(compressed)
    path = tmp_path / "s.mat"
    path.write_bytes(original)
    assert read_table(path).port_names == ("P1", "P2", "P3")
    errors = 0
    for position in range(0, len(original), 3):
        damaged = bytearray(original)
        damaged[position] ^= 0xA5
        path.write_bytes(bytes(damaged))
        try:
            read_table(path, allow_invalid=True)
        except WavemeterError as exc:
            assert str(exc).startswith(f"{path}: "), exc
            errors += 1
    assert errors > 10


# ---------------------------------------------------------------------------- NPZ
class _CountingZipExtFile:
    """Counts the bytes decompressed from zip members."""

    total = 0

    def __init__(self, monkeypatch):
        original = zipfile.ZipExtFile.read

        def read(member, size=-1):
            data = original(member, size)
            type(self).total += len(data)
            return data

        monkeypatch.setattr(zipfile.ZipExtFile, "read", read)


def test_npz_unused_large_member_is_never_decompressed(tmp_path, monkeypatch):
    path = tmp_path / "s.npz"
    np.savez_compressed(
        path,
        frequency_hz=FREQUENCY_HZ,
        P_W=POWERS_W,
        unused=np.zeros(4_000_000),  # 32 MB of zeros, about 30 kB compressed
    )
    assert path.stat().st_size < 200_000
    counter = _CountingZipExtFile(monkeypatch)
    table = read_table(path, max_bytes=1_000_000)
    assert table.n_rows == ROWS
    assert counter.total < 50_000


def test_npz_member_over_the_limit_is_refused_before_decompressing(tmp_path, monkeypatch):
    path = tmp_path / "s.npz"
    np.savez_compressed(path, frequency_hz=np.full(4_000_000, 193.4e12), P_W=POWERS_W)
    counter = _CountingZipExtFile(monkeypatch)
    with pytest.raises(FileFormatError, match="would take .* more than the 1 MB size limit"):
        read_table(path, max_bytes=1_000_000)
    assert counter.total < 50_000


def test_npz_with_a_pickle_is_refused(tmp_path):
    path = tmp_path / "s.npz"
    np.savez(path, frequency_hz=FREQUENCY_HZ, P_W=POWERS_W, note=np.array([{"a": 1}]))
    with pytest.raises(FileFormatError, match="'note' holds Python objects"):
        read_table(path)


@pytest.mark.slow
def test_one_damaged_byte_in_compressed_npz_gives_a_file_format_error(tmp_path):
    path = tmp_path / "s.npz"
    np.savez_compressed(path, frequency_hz=FREQUENCY_HZ, P_W=POWERS_W)
    original = path.read_bytes()
    errors = 0
    for position in range(0, len(original), 3):
        damaged = bytearray(original)
        damaged[position] ^= 0x55
        path.write_bytes(bytes(damaged))
        try:
            read_table(path, allow_invalid=True)
        except WavemeterError as exc:
            assert str(exc).startswith(f"{path}: "), exc
            assert "Error(" not in str(exc) and "Traceback" not in str(exc)
            errors += 1
    assert errors > 10


@pytest.mark.parametrize(
    ("column", "member"),
    [("../../x", "_.._.._x"), ("/etc/passwd", "_etc_passwd"), ("a\\b:c\n", "a_b_c_")],
)
def test_npz_member_names_are_made_safe(tmp_path, column, member):
    path = tmp_path / "out.npz"
    write_table(path, {"frequency_hz": FREQUENCY_HZ, column: FREQUENCY_HZ})
    with zipfile.ZipFile(path) as archive:
        assert archive.namelist() == ["frequency_hz.npy", f"{member}.npy"]
    with np.load(path) as archive:
        np.testing.assert_array_equal(archive[member], FREQUENCY_HZ)


def test_npz_member_names_that_collide_are_an_error(tmp_path):
    with pytest.raises(InputError, match="both become NPZ member 'a_b'"):
        write_table(tmp_path / "out.npz", {"a/b": FREQUENCY_HZ, "a_b": FREQUENCY_HZ})
    assert not (tmp_path / "out.npz").exists()


def test_npz_columns_named_like_savez_arguments_are_written(tmp_path):
    path = tmp_path / "out.npz"
    write_table(path, {"file": FREQUENCY_HZ, "allow_pickle": FREQUENCY_HZ})
    with np.load(path) as archive:
        assert sorted(archive.files) == ["allow_pickle", "file"]


# ---------------------------------------------------------------------------- streams
def test_dev_zero_is_refused_at_once():
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    start = time.perf_counter()
    with pytest.raises(FileFormatError, match="^/dev/zero: holds only NUL bytes"):
        read_table("/dev/zero")
    assert time.perf_counter() - start < 1.0


NEEDS_DEV_FD = pytest.mark.skipif(not os.path.isdir("/dev/fd"), reason="no /dev/fd")


@NEEDS_DEV_FD
def test_a_text_stream_longer_than_the_limit_is_refused(tmp_path):
    read_end, write_end = os.pipe()

    def write():
        with open(write_end, "wb") as handle:
            try:
                for _ in range(100):
                    handle.write(b"1,2,3,4\n" * 1000)
            except BrokenPipeError:
                pass

    writer = threading.Thread(target=write)
    writer.start()
    try:
        with pytest.raises(FileFormatError, match="not a regular file .* more than 100000"):
            read_table(f"/dev/fd/{read_end}", max_bytes=100_000)
    finally:
        os.close(read_end)
        writer.join()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs")
def test_fifo_is_read_once_as_a_stream(tmp_path):
    fifo = tmp_path / "sweep.csv"
    os.mkfifo(fifo)
    text = "# a comment\n" + _sweep_text().replace("\n1934", "\n\n1934", 1)

    def write():
        with open(fifo, "w") as handle:
            handle.write(text)

    writer = threading.Thread(target=write)
    writer.start()
    table = read_table(fifo, allow_invalid=True)
    writer.join()
    np.testing.assert_array_equal(table.x_hz, FREQUENCY_HZ)
    np.testing.assert_array_equal(table.powers_w, POWERS_W)


@NEEDS_DEV_FD
def test_process_substitution_pipe_with_a_bad_row_names_its_line():
    read_end, write_end = os.pipe()
    text = _sweep_text(5).splitlines()
    text[3] = text[3].replace(text[3].split(",")[2], "nan")
    with open(write_end, "w") as handle:
        handle.write("# comment\n" + "\n".join(text) + "\n")
    try:
        table = read_table(f"/dev/fd/{read_end}", allow_invalid=True)
    finally:
        os.close(read_end)
    assert table.n_rows == 5 and table.invalid.tolist() == [False, False, True, False, False]
    assert table.describe_invalid() == "line 5 (p2_w is NaN, empty or inf)"


# ---------------------------------------------------------------------------- CSV rows
def refuse(*args, **kwargs):
    """``numpy.loadtxt`` refusing its lines, as for a line it cannot parse."""
    raise ValueError("refused")


@pytest.mark.parametrize("parser", ["arrow", "numpy", "exact"])
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("frequency_hz,p1,p2,p3\n1.934e14,1,2,3\n1.935e14,1,2,3,4\n", "line 3 has 5 fields"),
        ("frequency_hz,p1,p2,p3\n1,934e14,1,2,3\n1,935e14,1,2,3\n", "line 2 has 5 fields"),
        ("# x\nfrequency_hz,p1,p2,p3\n\n1.934e14,1,2,3\n1.935e14,1,2\n", "line 5 has 3 fields"),
    ],
)
def test_rows_with_another_number_of_fields_name_their_line(
    tmp_path, monkeypatch, parser, text, expected
):
    if parser != "arrow":  # as where pyarrow is not installed
        monkeypatch.setitem(sys.modules, "pyarrow", None)
    if parser == "exact":  # numpy's reader refuses every piece
        monkeypatch.setattr(np, "loadtxt", refuse)
    path = _csv(tmp_path / "s.csv", text)
    with pytest.raises(FileFormatError, match=rf"^{path}: {expected}, the header has 4"):
        read_table(path)


def test_decimal_commas_in_a_comma_separated_file_are_named(tmp_path):
    path = _csv(tmp_path / "s.csv", "freq_THz,p1,p2,p3\n193,4,1,2,3\n193,5,1,2,3\n")
    with pytest.raises(FileFormatError, match=r"\(decimal commas in a comma-separated file\?"):
        read_table(path)


def test_a_trailing_delimiter_is_no_extra_field(tmp_path):
    path = _csv(tmp_path / "s.csv", "frequency_hz,p1,p2,p3\n1.934e14,1,2,3,\n1.935e14,1,2,3,\n")
    assert read_table(path).powers_w.tolist() == [[1, 2, 3], [1, 2, 3]]


@pytest.mark.parametrize(
    ("last", "truncated"),
    [
        ("1.93412e1", True),  # exponent cut
        ("1.934123", True),  # exponent lost
        ("1.9", True),  # mantissa cut
        ("1.934123e14", False),
        ("1.93412e14", False),  # one digit shorter: within the exponent part
        ("1.934123e14\n", False),
    ],
)
def test_last_line_cut_inside_its_number_is_reported(tmp_path, last, truncated):
    rows = "".join(f"{k},2,3,1.9341{k}3e14\n" for k in range(1, 7))
    path = _csv(tmp_path / "s.csv", "p1,p2,p3,frequency_hz\n" + rows + "7,2,3," + last)
    if truncated:
        with pytest.raises(FileFormatError, match=r"line 8 is probably truncated") as err:
            read_table(path)
        assert f"'{last}'" in str(err.value) and "'frequency_hz'" in str(err.value)
    else:
        assert read_table(path).n_rows == 7


def test_cut_exponent_is_not_a_number_and_says_truncated(tmp_path):
    path = _csv(tmp_path / "s.csv", "p1,p2,p3,frequency_hz\n1,2,3,1.93e14\n1,2,3,1.93e")
    with pytest.raises(FileFormatError, match=r"line 3, .* is not a number \(the last line has no"):
        read_table(path)


# ---------------------------------------------------------------------------- dBm
def test_implausible_and_overflowing_dbm_are_invalid_rows_with_file_lines(tmp_path):
    path = _csv(
        tmp_path / "dbm.csv",
        "# power meter\n"  # line 1
        "frequency_hz,p1_dBm,p2_dBm,p3_dBm\n"  # line 2
        "1.934e14,-3,-4,-5\n"  # line 3
        "\n"  # line 4
        "1.935e14,3100,-4,-5\n"  # line 5: overflows float64 as W
        "1.936e14,-3,70,-5\n"  # line 6: 10 kW
        "1.937e14,-3,-4,-5\n",  # line 7
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy overflow warning leaks
        with pytest.raises(InputError, match="2 invalid row") as err:
            read_table(path)
        table = read_table(path, allow_invalid=True)
    assert "line 5 (p1_dBm is above 60 dBm" in str(err.value)
    assert "line 6 (p2_dBm is above 60 dBm" in str(err.value)
    assert table.invalid.tolist() == [False, True, True, False]
    valid = table.valid_only()
    assert np.isfinite(valid.powers_w).all() and valid.n_rows == 2
    assert [valid.row_label(int(k)) for k in valid.row_index] == ["line 3", "line 7"]
    assert MAX_DBM == 60.0


@pytest.mark.parametrize(
    ("axis", "values"), [("wavelength_nm", "1550,0,1550.1"), ("freq_THz", "193.4,1e308,193.5")]
)
def test_axis_values_that_are_no_frequency_are_invalid_rows(tmp_path, axis, values):
    rows = "".join(f"{value},1,2,3\n" for value in values.split(","))
    path = _csv(tmp_path / "s.csv", f"{axis},p1,p2,p3\n" + rows)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy overflow or division warning leaks
        with pytest.raises(InputError, match=rf"line 3 \({axis} is not a frequency\)"):
            read_table(path)
        table = read_table(path, allow_invalid=True)
    assert table.invalid.tolist() == [False, True, False]
    assert np.isfinite(table.valid_only().x_hz).all()


def test_dbm_at_the_limit_is_valid(tmp_path):
    path = _csv(tmp_path / "dbm.csv", "frequency_hz,p1_dBm,p2_dBm,p3_dBm\n1.934e14,60,-4,-5\n")
    assert read_table(path).powers_w[0, 0] == pytest.approx(1e3)


# ---------------------------------------------------------------------------- CSV output
def test_csv_text_cells_that_look_like_formulas_get_a_quote(tmp_path):
    path = tmp_path / "out.csv"
    notes = np.array(["=1+2", "+cmd", "-x", "@SUM(A1)", "\tx", "-3.5", "plain", "1e5"])
    write_table(path, {"value": np.array([-3.5, 1.0, 2.0, 3, 4, 5, 6, 7]), "note": notes})
    lines = path.read_text().splitlines()
    assert [line.split(",", 1)[1] for line in lines[1:]] == [
        "'=1+2",
        "'+cmd",
        "'-x",
        "'@SUM(A1)",
        "'\tx",
        "-3.5",
        "plain",
        "1e5",
    ]
    assert lines[1].startswith("-3.5,")


# ---------------------------------------------------------------------------- messages
@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (b"MATLAB 5.0 MAT-file" + bytes(200), "cannot read it as a MATLAB file"),
        (b"PK\x03\x04" + bytes(100), "cannot read it as NPZ"),
        (b"\x89HDF\r\n\x1a\n" + bytes(100), "cannot read it as HDF5"),
        (b"PAR1" + bytes(100) + b"PAR1", "cannot read it as Parquet"),
        (b"\xff\xfef\x00r\x00", "is UTF-16 text"),
    ],
)
def test_foreign_files_name_the_file_and_no_python_internals(tmp_path, content, expected):
    path = tmp_path / ("s.mat" if content.startswith(b"MATLAB") else "s.dat")
    path.write_bytes(content)
    with pytest.raises(FileFormatError) as err:
        read_table(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and expected in message
    for internal in ("Error(", "Traceback", "unhashable", "startswith first arg", "KeyError"):
        assert internal not in message


def test_column_request_of_the_wrong_type_is_an_input_error(tmp_path):
    path = _csv(tmp_path / "s.csv", _sweep_text())
    with pytest.raises(InputError, match="ports must be a sequence of column names") as err:
        read_table(path, _request(ports="p1_w,p2_w,p3_w"))
    assert err.value.parameter == "ports"
    with pytest.raises(InputError, match=r"column names are text; got \['p1_w'\] for x"):
        read_table(path, _request(x=["p1_w"]))


def _request(**fields):
    from wavemeter.io import ColumnRequest

    return ColumnRequest(**fields)


@pytest.mark.slow
def test_tests_of_the_shared_data_skip_on_a_clone_without_it(tmp_path):
    """Issue 15: a fresh clone has no ../shared; its tests must skip, not fail."""
    tests = tmp_path / "clone" / "tests"
    tests.mkdir(parents=True)
    shutil.copy(Path(__file__).with_name("test_io.py"), tests / "test_io.py")
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-k", "minipti"]
        + ["-rs", str(tests / "test_io.py")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        check=False,
    )
    assert "1 skipped" in result.stdout and "failed" not in result.stdout, result.stdout


@pytest.mark.parametrize("name", ["q.xlsx", "cal.yaml", "out.mat", "x.json"])
def test_output_extension_no_writer_knows_is_an_error(name):
    with pytest.raises(InputError, match="cannot write") as err:
        table_format(name)
    assert err.value.parameter == "file_format"


@pytest.mark.parametrize(
    ("name", "expected"),
    [("a.CSV", "csv"), ("a.dat", "csv"), ("a.txt", "csv"), ("a", "csv"), ("-", "csv")],
)
def test_known_output_extensions_and_no_extension_are_csv(name, expected):
    assert table_format(name) == expected


# ---------------------------------------------------------------------------- standard streams
class _Stream:
    """Stands in for ``sys.stdin``/``sys.stdout``: text on top of a byte buffer."""

    def __init__(self, content: bytes = b""):
        self.buffer = io.BytesIO(content)

    def flush(self):
        pass


def test_dash_reads_standard_input_once(monkeypatch):
    monkeypatch.setattr("sys.stdin", _Stream(_sweep_text().encode()))
    table = read_table("-")
    np.testing.assert_array_equal(table.x_hz, FREQUENCY_HZ)
    assert str(table.source) == "-"


def test_dash_writes_standard_output(monkeypatch, tmp_path):
    stdout = _Stream()
    monkeypatch.setattr("sys.stdout", stdout)
    write_table("-", {"frequency_hz": FREQUENCY_HZ[:2]})
    assert stdout.buffer.getvalue() == b"frequency_hz\n193400000000000.0\n193401000000000.0\n"
    assert not (tmp_path / "-").exists() and not Path("-").exists()
