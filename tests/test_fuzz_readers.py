"""Fuzzing every reader: any bytes either read as a sound table or raise a clean error.

Files of every format are built from random arrays (and text tables from random cells,
dialects, encodings), then damaged byte by byte or cut short. ``read_table`` must return a
table whose valid rows are finite, or raise :class:`~wavemeter.exceptions.WavemeterError`
(or ``OSError``) with a message that starts with the file name and shows no Python
internals, within a time limit. A subset goes through ``wavemeter measure``, which must
exit 0 or 2 and never raise.

A normal test run uses a fixed seed and a few hundred examples. ``make fuzz`` sets
``WAVEMETER_FUZZ_EXAMPLES`` (examples per reader; the CLI gets a tenth) and passes a seed
to ``--hypothesis-seed``, which it prints so that a failure can be repeated.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import warnings
import zipfile

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from scipy import io as scipy_io

import wavemeter as wm
from wavemeter.exceptions import WavemeterError
from wavemeter.io import read_table
from wavemeter.units import OPTICAL_BAND_HZ

pytestmark = pytest.mark.slow

FUZZ_EXAMPLES = int(os.environ.get("WAVEMETER_FUZZ_EXAMPLES", "0"))
SECONDS_PER_EXAMPLE = 20
#: text that betrays a Python internal in a message meant for a user
INTERNALS = (
    "Traceback",
    "unhashable type",
    "startswith first arg",
    "object has no attribute",
    "KeyError(",
    "Error(",
    "np.float64(",
    "<class ",
    "NoneType",
)


def fuzz_settings(examples: int):
    """``examples`` per test in a normal run (fixed seed), or what ``make fuzz`` asks."""
    return settings(
        max_examples=FUZZ_EXAMPLES or examples,
        derandomize=not FUZZ_EXAMPLES,
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )


class Hang(Exception):
    """A reader took longer than the time limit."""


@contextlib.contextmanager
def time_limit(seconds: float):
    def expire(signum, frame):
        raise Hang(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def read_or_refuse(path, **options) -> str:
    """Read ``path``; check the table, or that the error is clean. Returns what happened."""
    try:
        with time_limit(SECONDS_PER_EXAMPLE), warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)  # no numpy warning may leak
            table = read_table(path, **options)
    except WavemeterError as exc:
        message = str(exc)
        assert message.startswith(f"{path}: "), message
        assert not any(internal in message for internal in INTERNALS), message
        event(f"refused: {type(exc).__name__}")
        return "refused"
    except OSError as exc:
        event(f"refused: {type(exc).__name__}")
        return "refused"
    check_table(table)
    event("read")
    return "read"


def check_table(table) -> None:
    """What a table read from any file must satisfy."""
    rows, ports = table.powers_w.shape
    assert ports >= 3 and rows == table.n_rows == table.invalid_code.shape[0]
    valid = ~table.invalid
    assert np.isfinite(table.powers_w[valid]).all()
    assert (table.powers_w[valid].sum(axis=1) > 0).all()
    if table.x_hz is not None:
        finite = table.x_hz[valid]
        assert np.isfinite(finite).all()
        low, high = OPTICAL_BAND_HZ
        assert ((finite >= low * 0.999) & (finite <= high * 1.001)).all()
    for name, values in table.kept.items():
        assert values.shape == (rows,), name
    if table.invalid.any():
        assert table.describe_invalid(3).startswith(("line ", "row "))


# ---------------------------------------------------------------------------- damage
@st.composite
def damaged(draw, content: bytes) -> bytes:
    """``content`` with a few bytes flipped, set, deleted or inserted, or cut short."""
    data = bytearray(content)
    for _ in range(draw(st.sampled_from([0, 0, 0, 1, 1, 2, 4]))):  # half left whole
        if not data:
            break
        position = draw(st.integers(0, len(data) - 1))
        action = draw(st.sampled_from(["flip", "set", "delete", "insert", "cut"]))
        value = draw(st.integers(0, 255))
        if action == "flip":
            data[position] ^= 1 << (value % 8)
        elif action == "set":
            data[position] = value
        elif action == "delete":
            del data[position]
        elif action == "insert":
            data.insert(position, value)
        else:
            del data[position:]
    return bytes(data)


# ---------------------------------------------------------------------------- random content
NAMES = [
    "frequency_hz",
    "freq_THz",
    "wavelength_nm",
    "Wavelength (nm)",
    "lambda [um]",
    "p1",
    "p2",
    "p3",
    "p4",
    "P1_mW",
    "P2_mW",
    "P3_mW",
    "port1_dBm",
    "port2_dBm",
    "port3_dBm",
    "DC CH1",
    "DC CH2",
    "DC CH3",
    "P",
    "P_W",
    "signals",
    "monitor_mW",
    "temperature_C",
    "temp",
    "time",
    "note",
    "",
    "p1_furlong",
    "=cmd",
    "é λ",
]
REALISTIC = {
    "frequency_hz": st.floats(193.3e12, 193.5e12),
    "freq_THz": st.floats(193.3, 193.5),
    "wavelength_nm": st.floats(1549.0, 1551.0),
    "p1_w": st.floats(1e-6, 2e-3),
    "p2_w": st.floats(1e-6, 2e-3),
    "p3_w": st.floats(1e-6, 2e-3),
    "port1_dBm": st.floats(-40.0, 5.0),
    "port2_dBm": st.floats(-40.0, 5.0),
    "port3_dBm": st.floats(-40.0, 5.0),
    "monitor_mW": st.floats(0.5, 1.5),
    "temperature_C": st.floats(20.0, 30.0),
}
ODD_CELLS = st.sampled_from(
    ["", "nan", "NaN", "inf", "-inf", "N/A", "9.91E+37", "-200", "1,5", "1e", "-", "0", "1e999"]
)
ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True)


def cell_text(value) -> str:
    return repr(float(value)) if isinstance(value, float) else str(value)


@st.composite
def text_tables(draw) -> bytes:
    """A delimited text table, realistic or random, in a random dialect, maybe damaged."""
    if draw(st.booleans()):
        names = ["frequency_hz", "p1_w", "p2_w", "p3_w"]
        names = draw(st.sampled_from([names, ["wavelength_nm", *names[1:]], list(REALISTIC)]))
        rows = draw(st.integers(1, 12))
        odd = st.integers(0, 19).map(lambda k: k == 0)  # one cell in 20 is odd

        def cell(name):
            return draw(ODD_CELLS) if draw(odd) else cell_text(draw(REALISTIC[name]))

        cells = [[cell(name) for name in names] for _ in range(rows)]
    else:
        names = draw(st.lists(st.sampled_from(NAMES), min_size=1, max_size=6))
        rows = draw(st.integers(0, 8))
        cell = st.one_of(ANY_FLOAT.map(cell_text), ODD_CELLS, st.text(max_size=6))
        cells = [[draw(cell) for _ in names] for _ in range(rows)]
    delimiter = draw(st.sampled_from([",", "\t", ";", " ", "  "]))
    quote = '"' if draw(st.booleans()) else ""
    newline = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    lines = [delimiter.join(f"{quote}{cell}{quote}" for cell in row) for row in [names, *cells]]
    prefix = draw(st.sampled_from(["", "\ufeff", "# exported\n", "\n\n", "#\n\n"]))
    text = prefix + newline.join(lines) + draw(st.sampled_from([newline, ""]))
    encoding = draw(st.sampled_from(["utf-8"] * 5 + ["latin-1"] * 4 + ["utf-16"]))
    return draw(damaged(text.encode(encoding, errors="replace")))


@st.composite
def arrays(draw) -> dict[str, np.ndarray]:
    """Named arrays: a sweep (axis and ports, vectors or a matrix) plus random extras."""
    rows = draw(st.integers(1, 12))
    dtype = draw(st.sampled_from([np.float64, np.float32, np.int16, np.uint8, np.bool_]))
    content: dict[str, np.ndarray] = {}
    if draw(st.booleans()):
        axis = draw(st.sampled_from(["frequency_hz", "wavelength_nm", "freq_THz"]))
        low = {"frequency_hz": 193.3e12, "wavelength_nm": 1549.0, "freq_THz": 193.3}[axis]
        content[axis] = low * (1 + np.linspace(0, 1e-3, rows))
    values = draw(
        st.lists(st.one_of(st.floats(1e-6, 1e-2), ANY_FLOAT), min_size=3 * rows, max_size=3 * rows)
    )
    ports = np.array(values).reshape(rows, 3)
    if draw(st.booleans()):
        name = draw(st.sampled_from(["P_W", "P", "signals", "ports"]))
        content[name] = ports.T if draw(st.booleans()) else ports
    else:
        for k in range(3):
            content[draw(st.sampled_from([f"p{k + 1}_w", f"P{k + 1}_mW", f"port{k + 1}_dBm"]))] = (
                ports[:, k]
            )
    for _ in range(draw(st.integers(0, 2))):
        shape = draw(st.sampled_from([(rows,), (rows, 1), (0,), (2, 2, 2), (1, rows)]))
        content[draw(st.sampled_from(NAMES))] = np.ones(shape, dtype=dtype)
    return {name or "unnamed": value for name, value in content.items()}


READ_OPTIONS = st.fixed_dictionaries(
    {
        "need_x": st.booleans(),
        "allow_invalid": st.booleans(),
        "max_bytes": st.sampled_from([2**31, 2**31, 2**31, 10_000, 100]),
    }
)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


def _write(folder, name: str, content: bytes):
    path = folder / name
    path.write_bytes(content)
    return path


# ---------------------------------------------------------------------------- readers
@fuzz_settings(150)
@given(
    content=text_tables(),
    suffix=st.sampled_from([".csv", ".tsv", ".txt", ""]),
    options=READ_OPTIONS,
)
def test_text_tables_read_or_refuse(folder, content, suffix, options):
    read_or_refuse(_write(folder, f"table{suffix}", content), **options)


@fuzz_settings(60)
@given(
    content=st.binary(max_size=600),
    suffix=st.sampled_from([".csv", ".h5", ".npz", ".mat", ".parquet"]),
)
def test_random_bytes_read_or_refuse(folder, content, suffix):
    read_or_refuse(_write(folder, f"random{suffix}", content))


def _npz_bytes(content, compressed: bool) -> bytes:
    buffer = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buffer, **content)
    return buffer.getvalue()


@fuzz_settings(60)
@given(content=arrays(), compressed=st.booleans(), data=st.data(), options=READ_OPTIONS)
def test_npz_reads_or_refuses(folder, content, compressed, data, options):
    raw = data.draw(damaged(_npz_bytes(content, compressed)))
    read_or_refuse(_write(folder, "s.npz", raw), **options)


def _hdf5_bytes(folder, content, *, matlab: bool, compressed: bool, units: str | None) -> bytes:
    path = folder / "build.h5"
    with h5py.File(path, "w", userblock_size=512 if matlab else 0) as handle:
        group = handle if matlab else handle.create_group("scan")
        for name, value in content.items():
            array = value.T if matlab else value
            options = {"compression": "gzip", "chunks": True} if compressed and array.ndim else {}
            dataset = group.create_dataset(name.replace("/", "_"), data=array, **options)
            if matlab:
                dataset.attrs["MATLAB_class"] = np.bytes_("double")
            elif units:
                dataset.attrs["units"] = units
    raw = path.read_bytes()
    if matlab:
        header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116)
        raw = header + raw[116:]
    return raw


@fuzz_settings(60)
@given(
    content=arrays(),
    compressed=st.booleans(),
    units=st.sampled_from([None, "THz", "mW", "furlong"]),
    data=st.data(),
    options=READ_OPTIONS,
)
def test_hdf5_reads_or_refuses(folder, content, compressed, units, data, options):
    raw = _hdf5_bytes(folder, content, matlab=False, compressed=compressed, units=units)
    read_or_refuse(_write(folder, "s.h5", data.draw(damaged(raw))), **options)


@fuzz_settings(40)
@given(content=arrays(), compressed=st.booleans(), data=st.data(), options=READ_OPTIONS)
def test_mat_v73_reads_or_refuses(folder, content, compressed, data, options):
    raw = _hdf5_bytes(folder, content, matlab=True, compressed=compressed, units=None)
    read_or_refuse(_write(folder, "s73.mat", data.draw(damaged(raw))), **options)


@fuzz_settings(60)
@given(
    content=arrays(),
    compressed=st.booleans(),
    structure=st.booleans(),
    data=st.data(),
    options=READ_OPTIONS,
)
def test_mat_v5_reads_or_refuses(folder, content, compressed, structure, data, options):
    variables = {name.replace(" ", "_").strip("=()[]é λ") or "x": v for name, v in content.items()}
    variables = {name: v for name, v in variables.items() if name.isidentifier()}
    if structure:
        variables = {"sweep": variables, "cells": np.array([1.0, "a"], dtype=object)}
    buffer = io.BytesIO()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", scipy_io.matlab.MatWriteWarning)
            scipy_io.savemat(buffer, variables, do_compression=compressed)
    except ValueError:  # a name or value scipy cannot write: nothing to read
        return
    read_or_refuse(_write(folder, "s5.mat", data.draw(damaged(buffer.getvalue()))), **options)


@fuzz_settings(40)
@given(content=arrays(), data=st.data(), options=READ_OPTIONS)
def test_parquet_reads_or_refuses(folder, content, data, options):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    columns = {name: value for name, value in content.items() if value.ndim == 1}
    lengths = {len(value) for value in columns.values()}
    if len(lengths) != 1:
        columns = {name: value for name, value in columns.items() if len(value) == max(lengths)}
    buffer = io.BytesIO()
    pq.write_table(pa.table({name: pa.array(value) for name, value in columns.items()}), buffer)
    read_or_refuse(_write(folder, "s.parquet", data.draw(damaged(buffer.getvalue()))), **options)


@fuzz_settings(40)
@given(content=arrays(), data=st.data())
def test_npz_archives_with_odd_members_read_or_refuse(folder, content, data):
    """Members that are not arrays, duplicated, in folders, or stored with other methods."""
    buffer = io.BytesIO()
    method = data.draw(
        st.sampled_from([zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2])
    )
    with zipfile.ZipFile(buffer, "w", compression=method) as archive:
        for name, value in content.items():
            member = data.draw(st.sampled_from([f"{name}.npy", f"dir/{name}.npy", name]))
            payload = io.BytesIO()
            np.save(payload, value)
            archive.writestr(member, payload.getvalue())
        if data.draw(st.booleans()):
            archive.writestr("extra.npy", data.draw(st.binary(max_size=80)))
    read_or_refuse(_write(folder, "odd.npz", data.draw(damaged(buffer.getvalue()))))


# ---------------------------------------------------------------------------- the CLI
@pytest.fixture(scope="module")
def calibration_file(folder):
    device = wm.Interferometer.table1(ports=3, seed=1)
    frequency = device.sweep_hz(400)
    powers = device.powers(frequency, 1e-3, 5e-7, rng=1)
    path = folder / "chip.wmcal.json"
    wm.Calibrator().fit(powers, frequency).save(path)
    readings = device.powers(device.sweep_hz(8), 1e-3, 5e-7, rng=2)
    return path, readings


@st.composite
def measure_inputs(draw, readings: np.ndarray):
    """A readings file in any format, realistic then maybe damaged, and its suffix."""
    kind = draw(st.sampled_from(["csv", "npz", "h5", "mat"]))
    names = draw(st.sampled_from([["p1", "p2", "p3"], ["P1_mW", "P2_mW", "P3_mW"]]))
    scale = 1e3 if names[0].endswith("mW") else 1.0
    content = {name: readings[:, k] * scale for k, name in enumerate(names)}
    if kind == "csv":
        text = ",".join(["time", *names]) + "\n"
        text += "".join(
            ",".join([f"=t{row}", *map(repr, (readings[row] * scale).tolist())]) + "\n"
            for row in range(len(readings))
        )
        raw = text.encode()
    elif kind == "npz":
        raw = _npz_bytes(content, draw(st.booleans()))
    elif kind == "h5":
        buffer = io.BytesIO()
        with h5py.File(buffer, "w") as handle:
            for name, values in content.items():
                handle.create_dataset(name, data=values)
        raw = buffer.getvalue()
    else:
        buffer = io.BytesIO()
        scipy_io.savemat(buffer, content, do_compression=draw(st.booleans()))
        raw = buffer.getvalue()
    return draw(damaged(raw)), kind


@fuzz_settings(30)
@given(data=st.data(), output=st.sampled_from(["csv", "npz", "h5", "parquet"]))
def test_measure_exits_0_or_2_and_never_raises(folder, calibration_file, data, output):
    from wavemeter.cli import main

    cal, readings = calibration_file
    if FUZZ_EXAMPLES and data.draw(st.integers(0, 9)):
        return  # make fuzz: the CLI gets a tenth of the examples of a reader
    raw, kind = data.draw(measure_inputs(readings))
    source = _write(folder, f"readings.{kind}", raw)
    out = folder / f"out.{output}"
    if out.exists():
        out.unlink()
    arguments = ["measure", str(cal), str(source), "-o", str(out), "--quiet"]
    if kind == "csv" and data.draw(st.booleans()):
        arguments += ["--keep", "time"]
    if data.draw(st.booleans()):
        arguments.append("--drop-invalid")
    stdout, stderr = io.StringIO(), io.StringIO()
    with time_limit(SECONDS_PER_EXAMPLE), contextlib.redirect_stdout(stdout):
        with contextlib.redirect_stderr(stderr):
            code = main(arguments)
    errors = stderr.getvalue()
    event(f"exit code {code}")
    assert code in (0, 2), errors
    assert "Traceback" not in errors
    if code == 2:
        assert errors.startswith("error: ") and errors.count("\n") == 1, errors
        assert not out.exists()
    else:
        assert out.exists()
