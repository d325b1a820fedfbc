"""Lab files (issue 29, item 11): delimiter and decimal mark, Excel's ``sep=`` line.

A ``;``-separated file written with decimal commas (European lab software) reads to the
same float64 values as the same file written the usual way, bit for bit, with every parser
(pyarrow, numpy, the exact line parser), whole and in chunks; it is found and noted when
not asked for. Excel's ``sep=X`` first line names the delimiter. A delimiter and a decimal
mark that cannot be told apart are refused, as is either for a file that is no text table.
The command line takes ``--delimiter`` and ``--decimal`` on every command that reads data
files, and the note is printed as ``note: ...``.
"""

from __future__ import annotations

import io
import json
import re
import sys
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.exceptions import FileFormatError, InputError, InputNote
from wavemeter.io import ColumnRequest, iter_readings, read_table, write_table
from wavemeter.io.text_layout import LineCells

from .helpers import one_error, simulated_files
from .helpers import run_cli as run

ROWS = 50
CHUNK_SIZES = (1, 7, ROWS, 1000)


@pytest.fixture(scope="module")
def usual(tmp_path_factory):
    """A sweep written the usual way (comma-separated, decimal points, float64 repr),
    with a kept time column; and its text."""
    rng = np.random.default_rng(29)
    columns = {
        "time_s": np.arange(ROWS) * 0.125,
        "frequency_hz": 193.4e12 + rng.uniform(-25e9, 25e9, ROWS),
        **{f"p{k}_mW": rng.uniform(1e-3, 1.0, ROWS) for k in (1, 2, 3)},
    }
    columns["p2_mW"][[3, 40]] = [-2.5e-05, 7.0]  # a small offset and an integer value
    path = tmp_path_factory.mktemp("lab") / "usual.csv"
    write_table(path, columns)
    return path


def european(text: str, sep: str = ";") -> str:
    """The text of a comma-separated table with decimal points as ``sep``-separated with
    decimal commas."""
    return text.replace(",", sep).replace(".", ",")


@pytest.fixture(params=["arrow", "numpy", "exact"])
def parser(request, monkeypatch):
    """Read with pyarrow's CSV parser, numpy's, or the exact line parser."""
    if request.param == "arrow":
        pytest.importorskip("pyarrow")
    else:  # as where pyarrow is not installed
        monkeypatch.setitem(sys.modules, "pyarrow", None)
    if request.param == "exact":  # numpy's reader refuses every piece
        monkeypatch.setattr(np, "loadtxt", refuse)
    return request.param


def refuse(*args, **kwargs):
    """``numpy.loadtxt`` refusing its lines, as for a line it cannot parse."""
    raise ValueError("refused")


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def assert_same_table(found, expected) -> None:
    assert same_bits(found.x_hz, expected.x_hz)
    assert same_bits(found.powers_w, expected.powers_w)
    assert found.port_names == expected.port_names
    assert [found.row_label(k) for k in range(3)] == [expected.row_label(k) for k in range(3)]


def read_noted(path, request=None, **options):
    """``read_table``, and the text of every InputNote it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = read_table(path, request, **options)
    notes = [str(entry.message) for entry in caught if entry.category is InputNote]
    return table, notes


# ---------------------------------------------------------------------------- decimal commas
def test_semicolons_and_decimal_commas_read_bit_for_bit_and_are_noted(usual, tmp_path, parser):
    path = tmp_path / "sweep.csv"
    path.write_text(european(usual.read_text()))
    assert path.read_text().splitlines()[1].count(";") == 4
    table, notes = read_noted(path, ColumnRequest(keep=("time_s",)))
    expected = read_table(usual, ColumnRequest(keep=("time_s",)))
    assert_same_table(table, expected)
    assert same_bits(table.kept["time_s"], expected.kept["time_s"])
    assert notes == [f"{path}: read as ';'-separated with decimal commas"]
    # asked for, it is no note
    table, notes = read_noted(path, ColumnRequest(delimiter=";", decimal=","))
    assert_same_table(table, expected)
    assert notes == []


@pytest.mark.parametrize("chunk_rows", CHUNK_SIZES)
def test_decimal_commas_read_in_chunks_give_the_whole_files_values(
    usual, tmp_path, parser, chunk_rows
):
    path = tmp_path / "sweep.csv"
    path.write_text(european(usual.read_text()))
    request = ColumnRequest(keep=("time_s",))
    expected = read_table(usual, request)
    with pytest.warns(InputNote, match=r"read as ';'-separated with decimal commas$"):
        stream = iter_readings(path, request, chunk_rows=chunk_rows, need_x=True)
    chunks = list(stream)
    assert all(chunk.n_rows <= chunk_rows for chunk in chunks)
    assert same_bits(np.concatenate([c.powers_w for c in chunks]), expected.powers_w)
    assert same_bits(np.concatenate([c.x_hz for c in chunks]), expected.x_hz)
    assert same_bits(np.concatenate([c.kept["time_s"] for c in chunks]), expected.kept["time_s"])
    assert stream.progress == ROWS and stream.progress_total == (ROWS, "rows")


@pytest.mark.parametrize("sep", ["\t", " ", "|"])
def test_decimal_commas_with_another_delimiter_are_read_when_asked_for(usual, tmp_path, sep):
    path = tmp_path / "sweep.txt"
    path.write_text(european(usual.read_text(), sep))
    request = ColumnRequest(delimiter=sep, decimal=",")
    table, notes = read_noted(path, request)
    assert_same_table(table, read_table(usual))
    assert notes == []
    if sep == "\t":  # sniffed as tab-separated, but the decimal mark is not guessed there
        with pytest.raises(FileFormatError) as error:
            read_table(path)
        assert str(error.value) == (
            f"{path}: line 2, column 'frequency_hz': "
            f"{usual.read_text().splitlines()[1].split(',')[1].replace('.', ',')!r} is not a "
            "number (a decimal comma? write decimal points, or give the decimal mark ',')"
        )
        assert error.value.parameter == "decimal"


def test_a_decimal_point_in_a_file_read_with_decimal_commas_is_no_number(tmp_path, parser):
    """With decimal commas, ``1.500`` may mean fifteen hundred: it is refused."""
    path = tmp_path / "s.csv"
    path.write_text("freq_THz;p1;p2;p3\n193,4;1,5;2;3\n193,5;1.500;2;3\n")
    with pytest.raises(FileFormatError) as error:
        read_table(path, ColumnRequest(decimal=","))
    assert str(error.value) == (
        f"{path}: line 3, column 'p1': '1.500' is not a number (a decimal point in a file "
        "read with decimal commas? give the decimal mark '.')"
    )
    assert error.value.parameter == "decimal"


def test_mixed_decimal_marks_are_not_taken_for_decimal_commas(tmp_path):
    path = tmp_path / "s.csv"
    path.write_text("freq_THz;p1;p2;p3\n193,4;1;2;3\n193.5;1;2;3\n")
    with pytest.raises(FileFormatError) as error:
        read_table(path)
    assert str(error.value) == (
        f"{path}: line 2, column 'freq_THz': '193,4' is not a number (a decimal comma? write "
        "decimal points, or give the decimal mark ',')"
    )


def test_semicolons_with_decimal_points_are_read_without_a_note(usual, tmp_path):
    path = tmp_path / "s.csv"
    path.write_text(usual.read_text().replace(",", ";"))
    table, notes = read_noted(path)
    assert_same_table(table, read_table(usual))
    assert notes == []


def test_the_note_is_a_public_warning_class():
    assert wm.InputNote is InputNote and issubclass(InputNote, UserWarning)
    assert not issubclass(InputNote, wm.CalibrationWarning)


def test_a_note_names_standard_input(usual, monkeypatch):
    content = european(usual.read_text()).encode()
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(content)))
    table, notes = read_noted("-")
    assert_same_table(table, read_table(usual))
    assert notes == ["<stdin>: read as ';'-separated with decimal commas"]


# ---------------------------------------------------------------------------- sep= line
@pytest.mark.parametrize(
    ("first", "sep"), [("sep=;", ";"), ('"sep=;"', ";"), ("SEP=;;;;", ";"), ("sep=,", ",")]
)
def test_excels_sep_line_names_the_delimiter_and_is_no_header(usual, tmp_path, parser, first, sep):
    text = usual.read_text().replace(",", sep)
    path = tmp_path / "excel.csv"
    path.write_text(f"{first}\r\n" + text.replace("\n", "\r\n"))
    table = read_table(path, ColumnRequest(keep=("time_s",)))
    expected = read_table(usual, ColumnRequest(keep=("time_s",)))
    assert same_bits(table.powers_w, expected.powers_w)
    assert same_bits(table.kept["time_s"], expected.kept["time_s"])
    assert table.row_label(0) == "line 3"  # file lines: the sep= line counts


def test_a_sep_line_with_decimal_commas_is_noted(usual, tmp_path):
    path = tmp_path / "excel.csv"
    path.write_text("sep=;\n" + european(usual.read_text()))
    table, notes = read_noted(path)
    assert same_bits(table.powers_w, read_table(usual).powers_w)
    assert table.row_label(0) == "line 3"
    assert notes == [f"{path}: read as ';'-separated with decimal commas"]


def test_the_delimiter_asked_for_wins_over_the_sep_line(usual, tmp_path):
    path = tmp_path / "excel.csv"
    path.write_text("sep=;\n" + usual.read_text())
    found = read_table(path, ColumnRequest(delimiter=","))
    assert same_bits(found.powers_w, read_table(usual).powers_w)
    with pytest.raises(FileFormatError) as error:
        read_table(path)  # split at ';' as the file says: one column
    assert str(error.value) == (
        f"{path}: the header row is a single column when split at semicolon (as its sep= "
        "line says): is that the delimiter? give the delimiter"
    )
    assert error.value.parameter == "delimiter"


def test_a_sep_line_naming_no_delimiter_is_refused(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_text("sep=.\nfrequency_hz.p1.p2.p3\n")
    with pytest.raises(FileFormatError) as error:
        read_table(path)
    assert str(error.value) == (
        f"{path}: the first line 'sep=.' names '.' as the delimiter, which cannot be one; "
        "give the delimiter"
    )


# ---------------------------------------------------------------------------- refused
@pytest.mark.parametrize(
    ("request_", "message", "parameter"),
    [
        (
            ColumnRequest(delimiter=",", decimal=","),
            "the delimiter and the decimal mark cannot both be ',': 1,5 would be two cells and "
            "one number; give another delimiter or decimal mark",
            "decimal",
        ),
        (
            ColumnRequest(delimiter=";;"),
            "delimiter must be one character such as ',', ';', '\\t' or ' ' (runs of spaces), "
            "not a letter, digit, quote or one of . + - #; got ';;'",
            "delimiter",
        ),
        (
            ColumnRequest(delimiter="."),
            "delimiter must be one character such as ',', ';', '\\t' or ' ' (runs of spaces), "
            "not a letter, digit, quote or one of . + - #; got '.'",
            "delimiter",
        ),
        (ColumnRequest(decimal=";"), "decimal must be '.' or ','; got ';'", "decimal"),
    ],
)
def test_a_delimiter_and_decimal_mark_that_cannot_be_are_refused(
    usual, request_, message, parameter
):
    for read in (read_table, iter_readings):
        with pytest.raises(InputError) as error:
            read(usual, request_)
        assert str(error.value) == f"{usual}: {message}"
        assert error.value.parameter == parameter


def test_a_sep_line_naming_the_decimal_mark_is_refused(usual, tmp_path):
    path = tmp_path / "excel.csv"
    path.write_text("sep=,\n" + usual.read_text())
    with pytest.raises(FileFormatError) as error:
        read_table(path, ColumnRequest(decimal=","))
    assert str(error.value) == (
        f"{path}: the first line names ',' as the delimiter, and it is the decimal mark asked "
        "for; give another decimal mark"
    )


def test_a_decimal_mark_asked_for_is_no_delimiter_candidate(usual, tmp_path):
    with pytest.raises(FileFormatError) as error:
        read_table(usual, ColumnRequest(decimal=","))
    assert str(error.value) == (
        f"{usual}: cannot tell the column delimiter (tried tab, semicolon, spaces): the header "
        "row has a single column"
    )


@pytest.mark.parametrize(("name", "kind"), [("s.h5", "HDF5"), ("s.npz", "NPZ")])
def test_a_file_of_another_format_has_no_delimiter_or_decimal_mark(usual, tmp_path, name, kind):
    path = tmp_path / name
    write_table(
        path, {"frequency_hz": np.full(4, 193.4e12), **{f"p{k}_w": np.ones(4) for k in (1, 2, 3)}}
    )
    for parameter, value in (("delimiter", ";"), ("decimal", ",")):
        with pytest.raises(InputError) as error:
            read_table(path, ColumnRequest(**{parameter: value}))
        assert str(error.value) == (
            f"{path}: is a {kind} file, not a text table: it has no {parameter} (given "
            f"{value!r}); leave the {parameter} out"
        )
        assert error.value.parameter == parameter


# ---------------------------------------------------------------------------- rows counted
@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"])
@pytest.mark.parametrize(
    ("text", "total"),
    [
        ("a,p1,p2,p3\n1,1,1,1\n2,2,2,2\n", 2),
        ("a,p1,p2,p3\n1,1,1,1\n2,2,2,2", 2),  # no newline at the end
        ("sep=,\n# comment\n\na,p1,p2,p3\n1,1,1,1\n2,2,2,2\n", 2),  # before the header
        ("a,p1,p2,p3\n1,1,1,1\n\n\n2,2,2,2\n\n", 5),  # blank lines after it count
    ],
)
def test_a_text_files_rows_are_counted_for_progress(tmp_path, text, newline, total):
    path = tmp_path / "r.csv"
    path.write_bytes(text.replace("\n", newline).encode())
    stream = iter_readings(path, chunk_rows=1, allow_invalid=True)
    assert stream.progress_total == (total, "rows")
    progress = []
    for _ in stream:
        progress.append(stream.progress)
    assert progress == [1, 2]


# ---------------------------------------------------------------------------- streams
def test_a_streams_cells_follow_the_files_rules():
    cells = LineCells("p1;p2;p3", source="<stdin>")
    assert cells.delimiter == ";"
    with pytest.warns(InputNote, match=r"^<stdin>: read as ';'-separated with decimal commas$"):
        assert [cells.number(c) for c in cells.split("1,5;2;-0,25e-3")] == [1.5, 2.0, -0.00025]
    with pytest.raises(ValueError):
        cells.number("1.5")  # decided: decimal commas
    points = LineCells("p1;p2;p3")
    assert [points.number(c) for c in points.split("2;1.5;1,5")[:2]] == [2.0, 1.5]
    with pytest.raises(ValueError):
        points.number("1,5")
    assert LineCells("p1\tp2,x").delimiter == "\t"
    assert LineCells("p1,p2;x").delimiter == ","
    assert LineCells("p1 p2", " ").split("1  2 ") == ["1", "2"]
    with pytest.raises(InputError, match="cannot both be ','"):
        LineCells("p1,p2", ",", ",")


def test_stream_reads_semicolons_with_decimal_commas_as_the_usual_lines(tmp_path, capsys):
    files = simulated_files(tmp_path, 30)
    semicolons = tmp_path / "semi.csv"
    semicolons.write_text("sep=;\n" + european(files["test"].read_text()))
    outputs = []
    for path in (files["test"], semicolons):
        code, out, err = stream_file(capsys, files["cal"], path)
        assert code == 0, err
        outputs.append((out, err))
    assert outputs[1][0] == outputs[0][0] and outputs[0][0].count("\n") == 31
    assert (
        outputs[1][1].splitlines()[0] == "note: <stdin>: read as ';'-separated with decimal commas"
    )
    assert "note:" not in outputs[0][1]


def stream_file(capsys, cal, path):
    """``wavemeter stream CAL < path``: exit code, stdout, stderr."""
    stdin = sys.stdin
    sys.stdin = io.TextIOWrapper(io.BytesIO(path.read_bytes()))
    try:
        return run(capsys, f"stream {cal}")
    finally:
        sys.stdin = stdin


# ---------------------------------------------------------------------------- command line
COMMANDS_READING_FILES = [
    "calibrate",
    "measure",
    "stream",
    "evaluate",
    "report",
    "reanchor",
    "noise",
    "fleet calibrate",
]


@pytest.mark.parametrize("command", COMMANDS_READING_FILES)
def test_every_command_that_reads_data_files_takes_delimiter_and_decimal(capsys, command):
    code, out, _ = run(capsys, f"{command} --help")
    assert code == 0
    assert re.search(r"--delimiter CHAR\s+Column delimiter of CSV/TSV input", out), out
    assert re.search(r"--decimal \[\.\|,\]\s+Decimal mark of CSV/TSV input", out), out


def test_calibrate_notes_decimal_commas_and_writes_the_usual_calibration(tmp_path, capsys):
    files = simulated_files(tmp_path, 10)
    semi = tmp_path / "semi.csv"
    semi.write_text(european(files["sweep"].read_text()))
    out = tmp_path / "semi.wmcal.json"
    code, _, err = run(capsys, f"calibrate {semi} -o {out}")
    assert code == 0, err
    assert err.splitlines() == [f"note: {semi}: read as ';'-separated with decimal commas"]
    found, expected = json.loads(out.read_text()), json.loads(files["cal"].read_text())
    for record in (found, expected):
        record.pop("created_utc")
        record["metadata"].pop("sweep_file")
    assert found == expected
    code, _, err = run(capsys, f"calibrate {semi} -o {tmp_path / 'q.wmcal.json'} --quiet")
    assert code == 0 and err == ""


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (
            "--delimiter , --decimal ,",
            "{sweep}: the delimiter and the decimal mark cannot both be ',': 1,5 would be two "
            "cells and one number; give another delimiter or decimal mark (decimal: --decimal)",
        ),
        (
            "--delimiter tab",
            "{sweep}: the header row is a single column when split at tab: is that the "
            "delimiter? give the delimiter (delimiter: --delimiter)",
        ),
        (
            "--delimiter ab",
            "Invalid value for '--delimiter': 'ab' is not one character: give the delimiter as "
            "one character (, ; |), or tab or space",
        ),
        (
            "--decimal ;",
            "Invalid value for '--decimal': ';' is not one of '.', ','.",
        ),
    ],
)
def test_delimiters_and_decimal_marks_that_cannot_be_are_one_error(
    tmp_path, capsys, options, expected
):
    files = simulated_files(tmp_path, 10)
    out = tmp_path / "x.wmcal.json"
    err = one_error(*run(capsys, f"calibrate {files['sweep']} -o {out} {options}")[::2])
    assert err == "error: " + expected.format(sweep=files["sweep"]) + "\n"
    assert not out.exists()


def test_measure_passes_the_decimal_mark_to_its_reader(tmp_path, capsys):
    files = simulated_files(tmp_path, 20)
    semi = tmp_path / "semi-test.csv"
    semi.write_text(european(files["test"].read_text()))
    outputs = []
    for data, options in ((files["test"], ""), (semi, "--delimiter ';' --decimal , --quiet")):
        out = tmp_path / f"m-{data.stem}.csv"
        code, _, err = run(capsys, f"measure {files['cal']} {data} -o {out} {options}")
        assert code == 0 and err == "", err
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1]
