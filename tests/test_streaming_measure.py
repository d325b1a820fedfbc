"""Measuring in chunks: the same output whatever the chunk size and the format, the right
file lines for invalid rows across chunks, atomic output on failure, many files, memory
that does not grow with the file."""

from __future__ import annotations

import contextlib
import csv
import resource
import shlex
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import wavemeter as wm
from wavemeter.calibration.contract.flags import ReadingFlag
from wavemeter.exceptions import FileFormatError, InputError
from wavemeter.io import ColumnRequest, iter_readings, read_table, write_table
from wavemeter.jobs import measure_file

from .helpers import one_error, run_cli, simulated_files, text_with_comments_and_blank_lines

ROWS = 60
#: rows whose port 2 reading is missing (NaN): invalid, skipped with drop_invalid
MISSING_ROWS = (0, 6, 7, 33, 59)
CHUNK_SIZES = (1, 7, 10_000)
OUTPUT_COLUMNS = ["frequency_hz", "wavelength_nm", "phase_rad", "frequency_std_hz", "flags"]


@pytest.fixture(scope="module")
def chip(tmp_path_factory) -> dict:
    """A learned calibration of a simulated chip and test readings with a time column."""
    folder = tmp_path_factory.mktemp("chip")
    files = simulated_files(folder, test_rows=ROWS, seed=3)
    table = read_table(files["test"], ColumnRequest(), need_x=False)
    powers = table.powers_w.copy()
    powers[list(MISSING_ROWS), 1] = np.nan
    return {
        "cal": files["cal"],
        "calibration": wm.load_calibration(files["cal"]),
        "powers": powers,
        "time_s": np.arange(ROWS) * 0.25,
    }


def columns_of(chip) -> dict[str, np.ndarray]:
    powers = chip["powers"]
    return {"time_s": chip["time_s"], **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}


def expected_output(chip) -> dict[str, np.ndarray]:
    """What measuring the whole file at once gives: the calibration on every valid row,
    NaN and INVALID on the others."""
    calibration, powers = chip["calibration"], chip["powers"]
    valid = np.isfinite(powers).all(axis=1)
    frequency = np.full(ROWS, np.nan)
    phase, std = frequency.copy(), frequency.copy()
    flags = np.full(ROWS, int(ReadingFlag.INVALID))
    frequency[valid] = calibration.predict(powers[valid])
    phase[valid] = calibration.phase(powers[valid])
    std[valid] = calibration.frequency_std_hz(powers[valid])
    flags[valid] = calibration.flags(powers[valid])
    return {
        "frequency_hz": frequency,
        "wavelength_nm": wm.units.SPEED_OF_LIGHT_M_S / frequency * 1e9,
        "phase_rad": phase,
        "frequency_std_hz": std,
        "flags": flags,
        "time_s": chip["time_s"],
    }


def write_input(path: Path, chip) -> Path:
    """The readings in the format of ``path``'s extension; ``_matrix`` in the name: the
    ports as one 2-D array (``_t``: ports x samples)."""
    columns = columns_of(chip)
    if "_matrix" in path.stem:
        matrix = chip["powers"].T if path.stem.endswith("_t") else chip["powers"]
        arrays = {"time_s": chip["time_s"], "P_W": matrix}
        if path.suffix == ".npz":
            np.savez_compressed(path, **arrays)
        else:
            with h5py.File(path, "w") as handle:
                for name, values in arrays.items():
                    handle.create_dataset(name, data=values, chunks=True)
        return path
    if path.suffix == ".parquet":  # small row groups: chunks cross them
        pq.write_table(pa.table(columns), path, row_group_size=11)
        return path
    write_table(path, columns)
    return path


def read_output(path: Path) -> dict[str, np.ndarray]:
    """The columns of an output file, in the order written (HDF5: as ``write_table``
    writes them, the output columns first)."""
    if path.suffix in (".csv", ".tsv"):
        delimiter = "," if path.suffix == ".csv" else "\t"
        header = path.read_text().splitlines()[0].split(delimiter)
        data = np.loadtxt(path, delimiter=delimiter, skiprows=1, ndmin=2)
        return {name: data[:, k] for k, name in enumerate(header)}
    if path.suffix == ".parquet":
        table = pq.read_table(path)
        return {name: table.column(name).to_numpy() for name in table.column_names}
    if path.suffix == ".h5":
        with h5py.File(path, "r") as handle:  # h5py lists datasets by name
            names = [name for name in OUTPUT_COLUMNS if name in handle]
            return {name: handle[name][()] for name in names + sorted(set(handle) - set(names))}
    with np.load(path) as archive:
        return {name: archive[name] for name in archive.files}


#: the calibration's batched linear algebra rounds differently with the batch size, so
#: results agree to float64 rounding, not bit for bit: 1e-12 relative (Hz, nm), 1e-12 rad,
#: far below the readings' own uncertainty (frequency_std_hz is MHz)
ROUNDING = {"rtol": 1e-12, "atol": 0.0}
PHASE_ROUNDING_RAD = 1e-12


def assert_same_output(found: dict, expected: dict) -> None:
    assert list(found)[: len(OUTPUT_COLUMNS)] == OUTPUT_COLUMNS
    for name, values in expected.items():
        if name == "phase_rad":
            np.testing.assert_allclose(found[name], values, rtol=0, atol=PHASE_ROUNDING_RAD)
        elif name in ("flags", "time_s"):
            np.testing.assert_array_equal(found[name], values, err_msg=name)
        else:
            np.testing.assert_allclose(found[name], values, **ROUNDING, err_msg=name)


# ---------------------------------------------------------------------------- same output
@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    ["r.csv", "r.tsv", "r.parquet", "r.h5", "r.npz", "r_matrix.h5", "r_matrix_t.h5",
     "r_matrix.npz", "r_matrix_t.npz"],
)  # fmt: skip
def test_every_input_format_gives_the_whole_file_result_at_any_chunk_size(chip, tmp_path, name):
    data = write_input(tmp_path / name, chip)
    expected = expected_output(chip)
    keep = ("time_s",)
    for chunk_rows in CHUNK_SIZES:
        out = tmp_path / f"out-{chunk_rows}.csv"
        progress = ProgressRecord()
        summary = measure_file(
            chip["calibration"],
            data,
            out,
            request=ColumnRequest(keep=keep),
            chunk_rows=chunk_rows,
            drop_invalid=True,
            progress=progress,
        )
        assert summary.rows == ROWS and summary.invalid_rows == len(MISSING_ROWS)
        assert_same_output(read_output(out), expected)
        # progress in rows for every format (a text file's counted before reading)
        assert (progress.total, progress.unit) == (ROWS, "rows")
        assert progress.steps == [
            min(k * chunk_rows, ROWS) for k in range(1, 1 - (-ROWS // chunk_rows))
        ]


class ProgressRecord:
    """A progress display that records what it is told: total, unit, position after each
    advance."""

    def __init__(self):
        self.total, self.unit, self.steps = None, None, []

    @contextlib.contextmanager
    def __call__(self, description, total, unit):
        self.total, self.unit = total, unit
        yield lambda steps: self.steps.append((self.steps[-1] if self.steps else 0) + steps)


@pytest.mark.parametrize("extension", [".csv", ".tsv", ".parquet", ".h5", ".npz"])
def test_every_output_format_holds_the_whole_file_result(chip, tmp_path, extension):
    data = write_input(tmp_path / "r.csv", chip)
    expected = expected_output(chip)
    for chunk_rows in CHUNK_SIZES:
        out = tmp_path / f"out-{chunk_rows}{extension}"
        measure_file(
            chip["calibration"],
            data,
            out,
            request=ColumnRequest(keep=("time_s",)),
            chunk_rows=chunk_rows,
            drop_invalid=True,
        )
        assert_same_output(read_output(out), expected)
    assert not list(tmp_path.glob(".*")), "temporary files left"


def test_kept_text_column_stays_text_across_chunks(chip, tmp_path):
    lines = ["label,p1_w,p2_w,p3_w"]
    powers = chip["powers"][~np.isnan(chip["powers"]).any(axis=1)][:20]
    lines += [f"run {k},{a!r},{b!r},{c!r}" for k, (a, b, c) in enumerate(powers.tolist())]
    data = tmp_path / "r.csv"
    data.write_text("\n".join(lines) + "\n")
    for chunk_rows in CHUNK_SIZES:
        out = tmp_path / f"o{chunk_rows}.parquet"
        request = ColumnRequest(keep=("label",))
        measure_file(chip["calibration"], data, out, request=request, chunk_rows=chunk_rows)
        labels = pq.read_table(out).column("label").to_pylist()
        assert labels == [f"run {k}" for k in range(20)]


def test_a_kept_column_of_numbers_that_turns_to_text_is_refused(chip, tmp_path):
    """A whole read would keep such a column as text; a chunked read has written numbers
    already, so it says where the text starts instead of writing a mixed column."""
    powers = chip["powers"][np.isfinite(chip["powers"]).all(axis=1)][:20]
    labels = [str(k) if k < 12 else f"run {k}" for k in range(20)]
    lines = ["label,p1_w,p2_w,p3_w"]
    lines += [
        f"{label},{a!r},{b!r},{c!r}"
        for label, (a, b, c) in zip(labels, powers.tolist(), strict=True)
    ]
    data, out = tmp_path / "r.csv", tmp_path / "o.csv"
    data.write_text("\n".join(lines) + "\n")
    request = ColumnRequest(keep=("label",))
    with pytest.raises(InputError, match=r"'label' holds numbers, then text at line 14 \('run 12'"):
        measure_file(chip["calibration"], data, out, request=request, chunk_rows=7)
    assert not out.exists()
    measure_file(chip["calibration"], data, out, request=request, chunk_rows=20)
    rows = list(csv.reader(out.read_text().splitlines()))
    assert [row[rows[0].index("label")] for row in rows[1:]] == labels


# ---------------------------------------------------------------------------- text chunks
@pytest.mark.slow
@pytest.mark.parametrize("parser", ["arrow", "lines"])
def test_invalid_rows_across_chunks_keep_their_file_lines(chip, tmp_path, monkeypatch, parser):
    text, line_of_row = text_with_comments_and_blank_lines(chip)
    data = tmp_path / "r.csv"
    data.write_text(text)
    if parser == "lines":
        monkeypatch.setitem(sys.modules, "pyarrow", None)  # as where it is not installed
    expected = [f"line {line_of_row[row]} (p2_w is NaN, empty or inf)" for row in MISSING_ROWS]
    for chunk_rows in CHUNK_SIZES:
        out = tmp_path / f"o{chunk_rows}.csv"
        summary = measure_file(
            chip["calibration"], data, out, chunk_rows=chunk_rows, drop_invalid=True
        )
        assert summary.invalid_examples == expected
        assert summary.flag_counts["INVALID"] == len(MISSING_ROWS)
        with pytest.raises(InputError) as refused:
            measure_file(chip["calibration"], data, tmp_path / "no.csv", chunk_rows=chunk_rows)
        message = f"{len(MISSING_ROWS)} invalid row(s): {', '.join(expected)}; fix or delete"
        assert message in str(refused.value) and str(refused.value).startswith(str(data))
        assert refused.value.parameter == "allow_invalid"
        assert not (tmp_path / "no.csv").exists()


def test_cli_note_names_the_skipped_rows_by_file_line(chip, tmp_path, capsys):
    text, line_of_row = text_with_comments_and_blank_lines(chip)
    data, out = tmp_path / "r.csv", tmp_path / "f.csv"
    data.write_text(text)
    code, printed, err = run_cli(capsys, f"measure {chip['cal']} {data} -o {out} --drop-invalid")
    assert code == 0, err
    first = ", ".join(
        f"line {line_of_row[row]} (p2_w is NaN, empty or inf)" for row in MISSING_ROWS[:3]
    )
    assert f"skipped {len(MISSING_ROWS)} invalid row(s), first: {first}\n" in err
    assert f"wrote {out} ({ROWS} rows)" in printed
    expected = expected_output(chip)
    del expected["time_s"]
    assert_same_output(read_output(out), expected)


@pytest.mark.parametrize("parser", ["arrow", "lines"])
def test_a_bad_cell_deep_in_the_file_is_named_by_its_line(chip, tmp_path, monkeypatch, parser):
    text, line_of_row = text_with_comments_and_blank_lines(chip)
    lines = text.split("\n")
    bad_line = line_of_row[40]
    fields = lines[bad_line - 1].split(",")
    lines[bad_line - 1] = ",".join([fields[0], "abc", *fields[2:]])
    data = tmp_path / "r.csv"
    data.write_text("\n".join(lines))
    if parser == "lines":
        monkeypatch.setitem(sys.modules, "pyarrow", None)  # as where it is not installed
    with pytest.raises(FileFormatError, match=rf"line {bad_line}, column 'p1_w': 'abc' is not"):
        list(iter_readings(data, chunk_rows=7, allow_invalid=True))


def test_a_truncated_last_line_is_refused_after_the_chunks(chip, tmp_path):
    text, line_of_row = text_with_comments_and_blank_lines(chip)
    data = tmp_path / "r.csv"
    data.write_text(text.rstrip("\n")[:-9])  # the last value cut, no newline
    with pytest.raises(FileFormatError, match=rf"line {line_of_row[-1]} is probably truncated"):
        list(iter_readings(data, chunk_rows=7, allow_invalid=True))


# ---------------------------------------------------------------------------- atomic output
@pytest.mark.parametrize("extension", [".csv", ".parquet", ".h5", ".npz"])
def test_a_failing_later_chunk_leaves_no_output(chip, tmp_path, extension):
    text, line_of_row = text_with_comments_and_blank_lines(chip)
    lines = text.split("\n")
    lines[line_of_row[50] - 1] = "1.0,2.0,oops,4.0"
    data = tmp_path / "r.csv"
    data.write_text("\n".join(lines))
    out = tmp_path / f"f{extension}"
    with pytest.raises(FileFormatError, match=f"line {line_of_row[50]}, column 'p2_w'"):
        measure_file(chip["calibration"], data, out, chunk_rows=7, drop_invalid=True)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["r.csv"]


@pytest.mark.parametrize("extension", [".csv", ".npz"])
def test_an_interrupt_leaves_an_existing_output_untouched(chip, tmp_path, monkeypatch, extension):
    data = write_input(tmp_path / "r.csv", chip)
    out = tmp_path / f"f{extension}"
    out.write_bytes(b"the previous results")
    calibration = chip["calibration"]
    readout = calibration.readout
    calls = []

    def interrupted_at_the_third_chunk(powers, **extra):
        calls.append(len(powers))
        if len(calls) == 3:
            raise KeyboardInterrupt
        return readout(powers, **extra)

    monkeypatch.setattr(calibration, "readout", interrupted_at_the_third_chunk)
    with pytest.raises(KeyboardInterrupt):
        measure_file(calibration, data, out, chunk_rows=7, drop_invalid=True)
    assert len(calls) == 3
    assert out.read_bytes() == b"the previous results"
    assert sorted(path.name for path in tmp_path.iterdir()) == sorted(["r.csv", out.name])


def test_cli_refuses_a_bad_cell_with_one_error_and_no_output(chip, tmp_path, capsys):
    text, line_of_row = text_with_comments_and_blank_lines(chip)
    lines = text.split("\n")
    lines[line_of_row[-3] - 1] = "1.0,2.0,oops,4.0"
    data, out = tmp_path / "r.csv", tmp_path / "f.csv"
    data.write_text("\n".join(lines))
    err = one_error(*run_cli(capsys, f"measure {chip['cal']} {data} -o {out} --drop-invalid")[::2])
    assert f"line {line_of_row[-3]}, column 'p2_w': 'oops' is not a number" in err
    assert not out.exists()


# ---------------------------------------------------------------------------- many files
def test_many_files_go_on_past_a_broken_one(chip, tmp_path, capsys):
    folder, outdir = tmp_path / "runs", tmp_path / "measured"
    folder.mkdir()
    write_input(folder / "a.csv", chip)
    write_input(folder / "c.parquet", chip)
    (folder / "b.csv").write_text("time_s,p1_w,p2_w,p3_w\n1,2,3\n")
    (folder / "notes.md").write_text("not data")
    command = f"measure {chip['cal']} {folder} -o {outdir} --drop-invalid"
    code, printed, err = run_cli(capsys, command)
    assert code == 2
    errors = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 2, err
    assert errors[0].startswith(f"error: {folder / 'b.csv'}: line 2 has 3 fields"), err
    assert errors[1] == "error: 1 of 3 files failed (see above)"
    assert sorted(path.name for path in outdir.iterdir()) == ["a.csv", "c.csv"]
    expected = expected_output(chip)
    del expected["time_s"]
    for name in ("a.csv", "c.csv"):
        assert_same_output(read_output(outdir / name), expected)
        assert f"wrote {outdir / name} ({ROWS} rows)" in printed
    assert "measured 2 of 3 files" in printed
    # the outputs exist now: a second run replaces them only with --force
    before = (outdir / "a.csv").read_bytes()
    refused = one_error(*run_cli(capsys, command)[::2])
    assert f"{outdir / 'a.csv'} already exists" in refused and "--force" in refused
    assert (outdir / "a.csv").read_bytes() == before


def test_many_files_by_glob_pattern_in_the_chosen_format(chip, tmp_path, capsys):
    for name in ("x1.csv", "x2.csv", "y.csv"):
        write_input(tmp_path / name, chip)
    outdir = tmp_path / "out"
    pattern = shlex.quote(str(tmp_path / "x*.csv"))
    command = f"measure {chip['cal']} {pattern} -o {outdir} --format parquet --drop-invalid"
    code, printed, err = run_cli(capsys, command + " --quiet")
    assert code == 0, err
    assert printed == ""
    assert sorted(path.name for path in outdir.iterdir()) == ["x1.parquet", "x2.parquet"]
    np.testing.assert_array_equal(
        read_output(outdir / "x2.parquet")["flags"], expected_output(chip)["flags"]
    )


# ---------------------------------------------------------------------------- memory
_PEAK = textwrap.dedent(
    """
    import sys
    import numpy as np
    import wavemeter as wm
    from wavemeter.io import ColumnRequest
    from wavemeter.jobs import measure_file
    rows, cal, data, out = int(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4]
    measure_file(wm.load_calibration(cal), data, out, chunk_rows=4096,
                 request=ColumnRequest(keep=("time_s",)))
    """
)


def _peak_rss_bytes(*args) -> int:
    """Peak resident memory (bytes) of one measuring subprocess (Linux: ru_maxrss in kB)."""
    code = (
        "import resource, subprocess, sys\n"
        f"subprocess.run([sys.executable, '-c', {_PEAK!r}, *sys.argv[1:]], check=True)\n"
        "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, check=True
    )
    return int(done.stdout.split()[-1]) * 1024


@pytest.mark.slow
@pytest.mark.skipif(sys.platform != "linux", reason="ru_maxrss in kB on Linux")
def test_peak_memory_does_not_grow_with_the_file(chip, tmp_path):
    """2e5 rows take no more than 1.2x the peak memory of 2e4 rows plus one chunk."""
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss > 0
    rng = np.random.default_rng(5)
    base = chip["powers"][np.isfinite(chip["powers"]).all(axis=1)]
    peaks = {}
    for rows in (20_000, 200_000):
        powers = base[rng.integers(0, len(base), rows)]
        data = tmp_path / f"r{rows}.csv"
        write_table(data, {"time_s": np.arange(rows) * 1e-3, "p1_w": powers[:, 0],
                           "p2_w": powers[:, 1], "p3_w": powers[:, 2]})  # fmt: skip
        peaks[rows] = _peak_rss_bytes(rows, chip["cal"], data, tmp_path / f"o{rows}.csv")
    chunk_bytes = 4096 * (4 + 6) * 8  # a chunk of readings and results, float64
    assert peaks[200_000] <= 1.2 * peaks[20_000] + chunk_bytes, peaks
