"""Data files: formats, column discovery, units, orientation, invalid rows, writers."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy import io as scipy_io

import wavemeter as wm
from wavemeter.io import ColumnRequest, port_key, read_table, table_format, write_table
from wavemeter.units import SPEED_OF_LIGHT_M_S, hz_to_axis, w_to_power

MINIPTI = Path(__file__).parents[2] / "shared" / "data" / "minipti-fiber-3x3"
ROWS = 48


@pytest.fixture(scope="module")
def readings() -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and port powers (W, 4 ports) of a Table 1 device over one FSR."""
    device = wm.Interferometer.table1(4, seed=3)
    frequency = device.sweep_hz(ROWS)
    return frequency, device.powers(frequency, 1e-3, 1e-7, rng=4)


@pytest.fixture(params=["arrow", "numpy"])
def parser(request, monkeypatch):
    """Run a text test with pyarrow's CSV parser and with numpy's."""
    if request.param == "arrow":
        pytest.importorskip("pyarrow")
    else:
        monkeypatch.setattr("wavemeter.io.text._pyarrow", lambda: None)
    return request.param


def write_csv(path: Path, header: list[str], columns: list[np.ndarray], delimiter=",") -> Path:
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle, delimiter=delimiter, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(zip(*[list(map(repr, c.tolist())) for c in columns], strict=True))
    return path


def write_mat73(path: Path, variables: dict[str, np.ndarray]) -> Path:
    """Write arrays the way MATLAB's ``save -v7.3`` does: HDF5 behind a 512-byte header,
    every array stored transposed (MATLAB is column-major), vectors as 1xN or Nx1."""
    with h5py.File(path, "w", userblock_size=512) as handle:
        for name, value in variables.items():
            array = np.asarray(value)
            matrix = array[np.newaxis, :] if array.ndim == 1 else array
            dataset = handle.create_dataset(name, data=matrix.T)
            dataset.attrs["MATLAB_class"] = np.bytes_("double")
        text = handle.create_dataset("comment", data=np.frombuffer(b"hi", np.uint8)[:, None])
        text.attrs["MATLAB_class"] = np.bytes_("char")
        handle.create_group("#refs#")
    with open(path, "r+b") as handle:
        handle.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116))
    return path


# ---------------------------------------------------------------------------- CSV columns
AXES = [
    ("frequency_hz", "Hz"),
    ("freq_THz", "THz"),
    ("wavelength_nm", "nm"),
    ("Wavelength (nm)", "nm"),
    ("lambda [um]", "um"),
    ("true_frequency_GHz", "GHz"),
]


@pytest.mark.parametrize(("axis", "unit"), AXES)
def test_frequency_axis_is_found_by_name_and_converted_to_hz(tmp_path, readings, axis, unit):
    frequency, powers = readings
    path = write_csv(
        tmp_path / "s.csv",
        [axis, "p1_w", "p2_w", "p3_w"],
        [hz_to_axis(frequency, unit), *powers[:, :3].T],
    )
    table = read_table(path)
    assert (table.x_column, table.x_unit) == (axis, unit)
    np.testing.assert_allclose(table.x_hz, frequency, rtol=4e-16, atol=0)


PORT_SCHEMES = [
    (["P1_mW", "P2_mW", "P3_mW", "P4_mW"], "mW"),
    (["port1_dBm", "port2_dBm", "port3_dBm", "port4_dBm"], "dBm"),
    (["Port 1 [uW]", "Port 2 [uW]", "Port 3 [uW]", "Port 4 [uW]"], "uW"),
    (["DC CH1", "DC CH2", "DC CH3", "DC CH4"], ""),
    (["p1", "p2", "p3", "p4"], ""),
    (["ch_1 (nW)", "ch_2 (nW)", "ch_3 (nW)", "ch_4 (nW)"], "nW"),
]


@pytest.mark.parametrize(("names", "unit"), PORT_SCHEMES)
def test_port_columns_are_found_in_port_order_with_their_unit(tmp_path, readings, names, unit):
    frequency, powers = readings
    order = [2, 0, 3, 1]  # columns shuffled in the file; ports come back in number order
    raw = w_to_power(powers, unit or "W")
    path = write_csv(
        tmp_path / "s.csv",
        ["frequency_hz"] + [names[k] for k in order],
        [frequency, *(raw[:, k] for k in order)],
    )
    table = read_table(path)
    assert table.port_names == tuple(names)
    assert table.port_units == (unit,) * 4
    np.testing.assert_allclose(table.powers_w, powers, rtol=2e-15 if unit == "dBm" else 4e-16)


def test_monitor_and_temperature_columns_are_found_and_converted(tmp_path, readings):
    frequency, powers = readings
    monitor = np.linspace(0.9e-5, 1.1e-5, ROWS)
    celsius = np.linspace(20.0, 21.0, ROWS)
    path = write_csv(
        tmp_path / "s.csv",
        ["frequency_hz", "p1_w", "p2_w", "p3_w", "Power monitor [uW]", "Temperature (C)"],
        [frequency, *powers[:, :3].T, monitor * 1e6, celsius],
    )
    table = read_table(path)
    assert (table.monitor_column, table.temperature_column) == (
        "Power monitor [uW]",
        "Temperature (C)",
    )
    np.testing.assert_allclose(table.monitor_w, monitor, rtol=1e-15)
    np.testing.assert_allclose(table.temperature_k, celsius + 273.15, rtol=1e-15)


@pytest.mark.parametrize(
    ("name", "values", "unit"),
    [("frequency", 193.4e12, "Hz"), ("wavelength", 1550.0, "nm"), ("Wavelength", 1.55, "um")],
)
def test_axis_without_unit_takes_the_only_unit_that_is_optical(tmp_path, name, values, unit):
    axis = values * np.linspace(1.0, 1.0001, 5)
    ports = [np.full(5, 1.0), np.full(5, 2.0), np.full(5, 3.0)]
    table = read_table(write_csv(tmp_path / "s.csv", [name, "p1", "p2", "p3"], [axis, *ports]))
    assert table.x_unit == unit


def test_overrides_choose_columns_and_units(tmp_path, readings):
    frequency, powers = readings
    path = write_csv(
        tmp_path / "s.csv",
        ["set_point", "freq_readback", "a", "b", "c", "note"],
        [hz_to_axis(frequency, "nm"), frequency, *w_to_power(powers[:, :3], "dBm").T, frequency],
    )
    request = ColumnRequest(x="set_point", x_unit="nm", ports=("c", "a", "b"), power_unit="dBm")
    table = read_table(path, request)
    assert table.port_names == ("c", "a", "b")
    np.testing.assert_allclose(table.powers_w, powers[:, [2, 0, 1]], rtol=2e-15)
    np.testing.assert_allclose(table.x_hz, frequency, rtol=4e-16)


@pytest.mark.skipif(not MINIPTI.exists(), reason="shared MiniPTI data not present")
def test_real_minipti_file_finds_the_dc_ports_and_no_axis():
    table = read_table(MINIPTI / "Decimation_Comercial.csv", need_x=False)
    assert table.port_names == ("DC CH1", "DC CH2", "DC CH3")
    assert table.port_units == ("", "", "")
    assert table.x_hz is None and table.n_rows == 3726
    with open(MINIPTI / "Decimation_Comercial.csv") as handle:
        rows = list(csv.reader(handle))
    assert table.powers_w[0].tolist() == [float(v) for v in rows[1][-3:]]
    assert table.powers_w[-1].tolist() == [float(v) for v in rows[-1][-3:]]


# ---------------------------------------------------------------------------- text layouts
@pytest.mark.parametrize(
    ("delimiter", "quoted"), [(",", False), ("\t", False), (";", False), (" ", False), (",", True)]
)
def test_delimiters_comments_bom_crlf_and_quotes(tmp_path, parser, readings, delimiter, quoted):
    frequency, powers = readings
    quote = '"' if quoted else ""
    names = ["frequency_hz", "p1_w", "p2_w", "p3_w"]
    lines = ["# exported by a power meter", "", delimiter.join(f"{quote}{n}{quote}" for n in names)]
    for f, row in zip(frequency.tolist(), powers[:, :3].tolist(), strict=True):
        lines.append(delimiter.join(f"{quote}{v!r}{quote}" for v in (f, *row)))
    path = tmp_path / "s.txt"
    path.write_bytes(b"\xef\xbb\xbf" + "\r\n".join(lines).encode() + b"\r\n")
    table = read_table(path)
    assert table.x_hz.tolist() == frequency.tolist()
    assert table.powers_w.tolist() == powers[:, :3].tolist()


def test_bad_rows_are_reported_with_file_line_numbers(tmp_path, parser):
    path = tmp_path / "lab.csv"
    path.write_text(
        "# Keysight 8164A\n"  # line 1
        "\n"
        "wavelength_nm,P1_mW,P2_mW,P3_mW\n"
        "1550.0,0.1,0.2,0.3\n"  # line 4
        "1550.1,nan,0.2,0.3\n"  # line 5: NaN
        "\n"
        "1550.2,0.1,9.91E+37,0.3\n"  # line 7: power-meter code
        "1550.3,0,0,0\n"  # line 8: no light
        "1550.4,,0.2,0.3\n"  # line 9: empty cell
        "1550.5,0.1,0.2,0.3\n"
    )
    with pytest.raises(ValueError, match="4 invalid row") as err:
        read_table(path)
    message = str(err.value)
    assert message.startswith(str(path))
    for expected in (
        "line 5 (P1_mW is NaN",
        "line 7 (P2_mW is a power-meter 'no reading' code 9.91e+37)",
        "line 8 (port powers sum to <= 0",
        "line 9 (P1_mW is NaN",
        "allow invalid rows",
    ):
        assert expected in message
    assert err.value.parameter == "allow_invalid" and "--" not in message
    table = read_table(path, allow_invalid=True)
    assert table.invalid.tolist() == [False, True, True, True, True, False]
    valid = table.valid_only()
    assert (valid.n_rows, valid.dropped_rows) == (2, 4)
    assert valid.x_hz == pytest.approx(SPEED_OF_LIGHT_M_S / np.array([1550.0e-9, 1550.5e-9]))


def test_minus_200_dbm_is_a_no_reading_code(tmp_path, parser):
    path = tmp_path / "dbm.csv"
    path.write_text("freq_THz,p1_dBm,p2_dBm,p3_dBm\n193.4,-3,-4,-200\n193.41,-3,-4,-5\n")
    with pytest.raises(
        ValueError, match=r"line 2 \(p3_dBm is a power-meter 'no reading' code -200"
    ):
        read_table(path)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("", "the file is empty"),
        ("\n\n", "the file is empty"),
        ("# only a comment\n", "no header row"),
        ("frequency_hz,p1,p2,p3\n", "header row but no data rows"),
        ("frequency_hz,p1,p1,p3\n1,2,3,4\n", "duplicate column name 'p1' (columns 2 and 3)"),
        ("frequency_hz,p1,p2,p3\n1.934e14,1,abc,3\n", "line 2, column 'p2': 'abc' is not a number"),
        (
            "frequency_hz,p1,p2,p3\n1.934e14,1,2,3\n1.935e14,1,N/A,3\n",
            "line 3, column 'p2': 'N/A' is not",
        ),
        ("freq_THz\tp1\tp2\tp3\n193,4\t1\t2\t3\n", "'193,4' is not a number (a decimal comma?"),
        ("frequency_hz,p1,p2,p3\n1.934e14,1,2\n", "line 2 has 3 fields, the header has 4"),
        ("frequency_hz,P1_mA,P2_mA,P3_mA\n1.934e14,1,2,3\n", "column 'P1_mA': unknown power unit"),
        ("freq_THz,p1,p2,p3\n1550,1,2,3\n", "labelled THz look like nm"),
        ("frequency_hz,wavelength_nm,p1,p2,p3\n1.934e14,1550,1,2,3\n", "name the one to use (x)"),
        ("time_s,p1,p2,p3\n1,1,2,3\n", "no frequency or wavelength column"),
        ("frequency_hz,a,b,c\n1.934e14,1,2,3\n", "no port columns"),
        ("frequency_hz,p1,p2\n1.934e14,1,2\n", "found 2 port column(s) (p1, p2); need at least 3"),
        ("frequency_hz,p1,P1_mW,p2,p3\n1.934e14,1,1,2,3\n", "repeat a port number"),
        ("frequency_hz,P1_mW,P2_mW,P3_mW\n1.934e14,-3,-4,-5\n", "are these dBm? give the power"),
        ("only\n1\n", "cannot tell the column delimiter"),
    ],
)
def test_bad_text_files_give_one_clear_error_naming_the_file(tmp_path, parser, text, expected):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError) as err:
        read_table(path)
    assert str(err.value).startswith(f"{path}: ")
    assert expected in str(err.value)


def test_temperature_needs_a_unit_when_chosen_and_is_skipped_when_found(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("frequency_hz,p1,p2,p3,temp\n1.934e14,1,2,3,20\n")
    assert read_table(path).temperature_k is None
    with pytest.raises(ValueError, match="temperature column 'temp' has no unit"):
        read_table(path, ColumnRequest(temperature="temp"))


def test_missing_requested_column_lists_the_columns(tmp_path, readings):
    frequency, powers = readings
    path = write_csv(
        tmp_path / "s.csv", ["frequency_hz", "p1", "p2", "p3"], [frequency, *powers[:, :3].T]
    )
    with pytest.raises(
        ValueError, match=r"no column 'nope' \(given as x\); columns: 'frequency_hz'"
    ) as err:
        read_table(path, ColumnRequest(x="nope"))
    assert err.value.parameter == "x"


@pytest.mark.parametrize("make", ["missing", "folder"])
def test_missing_file_or_folder(tmp_path, make):
    path = tmp_path / "data.csv"
    if make == "folder":
        path.mkdir()
    with pytest.raises(ValueError, match="file not found|is a folder"):
        read_table(path)


def test_ambiguous_axis_is_no_error_when_the_axis_is_not_needed(tmp_path, readings):
    frequency, powers = readings
    path = write_csv(
        tmp_path / "out.csv",
        ["frequency_hz", "wavelength_nm", "p1", "p2", "p3"],
        [frequency, hz_to_axis(frequency, "nm"), *powers[:, :3].T],
    )
    assert read_table(path, need_x=False).x_hz is None
    assert read_table(path, ColumnRequest(x="wavelength_nm")).x_unit == "nm"


def test_kept_text_columns_are_carried_verbatim(tmp_path, readings):
    frequency, powers = readings
    stamps = [f"2026-11-22T10:00:{k:02d}, run {k}" for k in range(ROWS)]
    path = tmp_path / "s.csv"
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["time", "frequency_hz", "p1", "p2", "p3"])
        for stamp, f, row in zip(stamps, frequency.tolist(), powers[:, :3].tolist(), strict=True):
            writer.writerow([stamp, repr(f), *map(repr, row)])
    table = read_table(path, ColumnRequest(keep=("time", "frequency_hz")))
    assert table.kept["time"].tolist() == stamps
    out = tmp_path / "out.csv"
    write_table(out, {"frequency_hz": table.x_hz, **table.kept})
    with open(out, newline="") as handle:
        rows = list(csv.reader(handle))
    assert [row[1] for row in rows[1:]] == stamps


# ---------------------------------------------------------------------------- array formats
def _check(table, frequency, powers, names=None):
    np.testing.assert_allclose(table.x_hz, frequency, rtol=4e-16, atol=0)
    np.testing.assert_allclose(table.powers_w, powers, rtol=4e-16, atol=0)
    if names is not None:
        assert table.port_names == tuple(names)


@pytest.mark.parametrize("transposed", [False, True])
def test_npz_with_a_port_matrix_in_either_orientation(tmp_path, readings, transposed):
    frequency, powers = readings
    path = tmp_path / "s.npz"
    np.savez(path, frequency_hz=frequency, P_mW=(powers.T if transposed else powers) * 1e3)
    _check(read_table(path), frequency, powers, ["P1", "P2", "P3", "P4"])


def test_npz_with_one_vector_per_port(tmp_path, readings):
    frequency, powers = readings
    path = tmp_path / "s.npz"
    np.savez(
        path,
        wavelength_nm=hz_to_axis(frequency, "nm"),
        **{f"p{k + 1}_w": powers[:, k] for k in range(4)},
    )
    _check(read_table(path), frequency, powers, ["p1_w", "p2_w", "p3_w", "p4_w"])


def test_square_port_matrix_is_ambiguous(tmp_path):
    path = tmp_path / "s.npz"
    np.savez(path, frequency_hz=np.array([193.4e12, 193.41e12, 193.42e12]), P=np.eye(3) + 1)
    with pytest.raises(ValueError, match="cannot tell samples from ports in 'P' of shape"):
        read_table(path)


def test_port_matrix_without_axis_takes_the_long_side_as_samples(tmp_path, readings):
    _, powers = readings
    long = np.tile(powers, (3, 1))  # 144 samples > 64 ports
    path = tmp_path / "s.npz"
    np.savez(path, signals=long.T)
    table = read_table(path, need_x=False)
    np.testing.assert_array_equal(table.powers_w, long)


def test_hdf5_groups_and_unit_attributes(tmp_path, readings):
    frequency, powers = readings
    path = tmp_path / "s.h5"
    with h5py.File(path, "w") as handle:
        scan = handle.create_group("scan")
        scan.create_dataset("frequency", data=frequency / 1e12).attrs["units"] = "THz"
        scan.create_dataset("ports", data=(powers * 1e3).T).attrs["units"] = "mW"
        scan.create_dataset("label", data="sweep 1")
    table = read_table(path)
    assert (table.x_column, table.x_unit) == ("scan/frequency", "THz")
    _check(table, frequency, powers, ["ports1", "ports2", "ports3", "ports4"])


@pytest.mark.parametrize("ports_as_rows", [False, True])
def test_mat_v5_with_a_struct(tmp_path, readings, ports_as_rows):
    frequency, powers = readings
    path = tmp_path / "s.mat"
    matrix = w_to_power(powers, "dBm")
    scipy_io.savemat(
        path,
        {
            "sweep": {
                "wavelength_nm": hz_to_axis(frequency, "nm"),
                "P_dBm": matrix.T if ports_as_rows else matrix,
            }
        },
    )
    table = read_table(path)
    assert table.x_column == "sweep/wavelength_nm"
    np.testing.assert_allclose(table.powers_w, powers, rtol=2e-15)


@pytest.mark.parametrize("ports_as_rows", [False, True])
def test_mat_v73_in_matlab_layout(tmp_path, readings, ports_as_rows):
    frequency, powers = readings
    path = write_mat73(
        tmp_path / "s.mat",
        {
            "frequency_hz": frequency[:, np.newaxis],  # a MATLAB column vector
            "P_W": powers.T if ports_as_rows else powers,
            "monitor_W": np.full(ROWS, 1e-5),  # a MATLAB row vector
        },
    )
    table = read_table(path)
    _check(table, frequency, powers, ["P1", "P2", "P3", "P4"])
    assert table.monitor_w.tolist() == [1e-5] * ROWS


def test_parquet_with_missing_values(tmp_path, readings):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    frequency, powers = readings
    p2 = pa.array([None if k == 5 else v for k, v in enumerate(powers[:, 1].tolist())])
    table = pa.table(
        {"freq_THz": frequency / 1e12, "p1_w": powers[:, 0], "p2_w": p2, "p3_w": powers[:, 2]}
    )
    path = tmp_path / "s.parquet"
    pq.write_table(table, path)
    with pytest.raises(ValueError, match=r"row 6 \(p2_w is NaN"):
        read_table(path)
    assert read_table(path, allow_invalid=True).valid_only().n_rows == ROWS - 1


def test_parquet_without_pyarrow_says_how_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    fake = tmp_path / "s.parquet"
    fake.write_bytes(b"PAR1" + bytes(64))
    with pytest.raises(ValueError, match=r"pip install 'wavemeter\[parquet\]'"):
        read_table(fake)
    with pytest.raises(ValueError, match=r"pip install 'wavemeter\[parquet\]'"):
        write_table(tmp_path / "out.parquet", {"a": np.zeros(2)})
    assert not (tmp_path / "out.parquet").exists()


def test_corrupt_binary_files_name_the_file(tmp_path):
    for name, head in (
        ("s.h5", b"\x89HDF\r\n\x1a\n"),
        ("s.npz", b"PK\x03\x04"),
        ("s.mat", b"MATLAB 5.0"),
    ):
        path = tmp_path / name
        path.write_bytes(head + bytes(40))
        with pytest.raises(ValueError, match=rf"^{path}: cannot read it as"):
            read_table(path)


# ---------------------------------------------------------------------------- writers
OUTPUT = {
    "frequency_hz": np.array([193414489032258.06, 193.4e12 + 1 / 3, np.nan]),
    "wavelength_nm": np.array([1550.0, 1550.1161220268873, np.nan]),
    "phase_rad": np.array([-np.pi, 0.1, np.nan]),
}


def _read_back(path: Path, file_format: str) -> dict[str, np.ndarray]:
    if file_format in ("csv", "tsv"):
        data = np.genfromtxt(path, delimiter="," if file_format == "csv" else "\t", names=True)
        return {name: data[name] for name in data.dtype.names}
    if file_format == "hdf5":
        with h5py.File(path) as handle:
            return {name: handle[name][()] for name in handle}
    if file_format == "npz":
        with np.load(path) as archive:
            return {name: archive[name] for name in archive.files}
    import pyarrow.parquet as pq

    return {
        name: column.to_numpy()
        for name, column in zip(*_names_columns(pq.read_table(path)), strict=True)
    }


def _names_columns(table):
    return table.column_names, table.columns


@pytest.mark.parametrize("file_format", ["csv", "tsv", "hdf5", "npz", "parquet"])
def test_writers_keep_every_bit_of_float64(tmp_path, file_format):
    if file_format == "parquet":
        pytest.importorskip("pyarrow")
    path = tmp_path / "out.data"
    write_table(path, OUTPUT, file_format)
    back = _read_back(path, file_format)
    assert list(back) == list(OUTPUT) or set(back) == set(OUTPUT)
    for name, values in OUTPUT.items():
        np.testing.assert_array_equal(back[name], values)


def test_csv_text_is_the_shortest_exact_repr(tmp_path):
    path = tmp_path / "out.csv"
    write_table(path, OUTPUT)
    lines = path.read_text().splitlines()
    assert lines[0] == "frequency_hz,wavelength_nm,phase_rad"
    assert lines[1] == "193414489032258.06,1550.0,-3.141592653589793"
    assert lines[3] == "nan,nan,nan"


def test_format_from_extension_and_failures_leave_no_file(tmp_path):
    names = ("a.csv", "a.tsv", "a.h5", "a.npz", "a.parquet", "a.txt", "a")
    assert [table_format(name) for name in names] == [
        "csv",
        "tsv",
        "hdf5",
        "npz",
        "parquet",
        "csv",
        "csv",
    ]
    with pytest.raises(ValueError, match="format must be one of"):
        table_format("a.csv", "xlsx")
    with pytest.raises(ValueError, match="cannot write MAT files"):
        table_format("a.mat")
    with pytest.raises(ValueError, match="different lengths"):
        write_table(tmp_path / "bad.csv", {"a": np.zeros(2), "b": np.zeros(3)})
    with pytest.raises(ValueError, match="does not exist"):
        write_table(tmp_path / "missing" / "out.csv", OUTPUT)
    assert list(tmp_path.iterdir()) == []


def test_port_key_ignores_units_and_spelling():
    assert port_key("Port 3 [uW]") == port_key("port_3_mW") == port_key("PORT3") == "port3"
    assert port_key("P1_dBm") == port_key("p1") != port_key("DC CH1")
